//! Prints what jointfit reads from C3D files: `cargo run -p jointfit-io --example c3d_dump -- FILE...`
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let show_params = args.iter().any(|a| a == "--params");
    for arg in args.iter().filter(|a| *a != "--params") {
        match jointfit_io::c3d::read_c3d(std::path::Path::new(&arg)) {
            Ok(c) => {
                let p = &c.points;
                let missing = p.positions.iter().filter(|v| v.x.is_nan()).count();
                println!(
                    "{arg}: {:?} {} frames (first {}) x {} points @ {} Hz, units {:?}, \
                     {missing} missing; analog {} ch x {} @ {} Hz",
                    c.processor,
                    p.n_frames,
                    p.first_frame,
                    p.n_points(),
                    p.rate,
                    c.units,
                    c.analog.n_channels(),
                    c.analog.n_samples(),
                    c.analog.rate
                );
                println!("  header {:?}", c.header);
                if show_params {
                    for (gname, g) in &c.parameters.groups {
                        for (pname, p) in &g.params {
                            let v = match p.strings() {
                                Some(s) => format!("{s:?}"),
                                None => format!("{:?}", p.f64s().unwrap_or_default()),
                            };
                            let v: String = v.chars().take(120).collect();
                            println!("  {gname}:{pname} {:?} = {v}", p.dims);
                        }
                    }
                }
                for w in &c.warnings {
                    println!("  warning: {w}");
                }
            }
            Err(e) => println!("{arg}: ERROR {e}"),
        }
    }
}
