fn main() {
    let c = jointfit_io::c3d::read_c3d(std::path::Path::new(&std::env::args().nth(1).unwrap()))
        .unwrap();
    let p = &c.points;
    let n = p.n_points();
    for f in [0usize, 60, 120] {
        let row = &p.positions[f * n..(f + 1) * n];
        println!(
            "frame {f}: {:?}",
            &row[..5]
                .iter()
                .map(|v| (v * 1000.0).map(|x| x.round()))
                .collect::<Vec<_>>()
        );
        let d = |a: usize, b: usize| ((row[a] - row[b]).norm() * 1000.0).round();
        println!(
            "  dists 2-3 {} 2-4 {} 3-4 {} 5-6 {} 5-7 {} 6-7 {}",
            d(2, 3),
            d(2, 4),
            d(3, 4),
            d(5, 6),
            d(5, 7),
            d(6, 7)
        );
    }
}
