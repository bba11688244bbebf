//! `jointfit bench --profile PART --repeat N`: one part of the bench alone, `N` times, for
//! profilers (`valgrind --tool=callgrind`) and quick A/B timings; prints each wall time and
//! the fastest. The parts are the code paths the bench times: `ik` (whole-trial IK of the
//! workload), `checked` (IK with the data checks, `jointfit::workflow::ik::ik_checked`), `before` (the
//! checks that need no IK), `after` (the moved-cluster check from the IK's fit), `read` and
//! `write` (the `ik_io` file steps on the workload repeated to `--io-frames` frames).

use std::time::Instant;

use anyhow::{bail, Result};
use jointfit::ik::{IkOptions, MarkerMap};
use jointfit::model::Model;
use jointfit::trial::Trial;

/// Runs `part` `repeat` times on the workload (`model`, `trial`); see the module docs.
pub fn run(
    model: &Model,
    trial: &Trial,
    part: &str,
    repeat: usize,
    io_frames: usize,
) -> Result<()> {
    let p = model.nominal_params();
    let opts = IkOptions::default();
    let for_model = crate::bench_cmd::for_model(model, trial)?;
    let (map, _) = MarkerMap::allowing_absent(model, for_model.labels());
    let fit = jointfit::workflow::ik::ik_trial(model, &p, &for_model, &opts)?.fit;
    // A private scratch folder (mode 0700, unpredictable name), removed when dropped.
    let scratch = crate::bench_perf::scratch_dir("jointfit-profile-")?;
    let trc = scratch.path().join("long.trc");
    let long = if part == "read" || part == "write" {
        let long = crate::bench_perf::repeat_trial(trial, io_frames)?;
        let text = jointfit_io::trc::format_trc(&long, "long.trc", &Default::default())?;
        std::fs::write(&trc, text)?;
        Some(long)
    } else {
        None
    };
    let long_fit = match (&long, part) {
        (Some(long), "write") => {
            Some(jointfit::workflow::ik::ik_trial(model, &p, long, &opts)?.fit)
        }
        _ => None,
    };
    let mut best = f64::INFINITY;
    let result = (|| -> Result<()> {
        for _ in 0..repeat {
            let t = Instant::now();
            match part {
                "ik" => {
                    std::hint::black_box(jointfit::workflow::ik::ik_trial(
                        model, &p, &for_model, &opts,
                    )?);
                }
                "checked" => {
                    let _ = std::hint::black_box(jointfit::workflow::ik::ik_checked(
                        model, &p, &for_model, &opts,
                    ));
                }
                "before" => {
                    std::hint::black_box(jointfit::checks::check_trial_before_ik(
                        model, &for_model, &map,
                    ));
                }
                "after" => {
                    std::hint::black_box(jointfit::checks::offsets::check_offsets(
                        model,
                        &for_model,
                        &map,
                        Some((&p, &opts, &fit)),
                    ));
                }
                "read" => {
                    std::hint::black_box(crate::common::load_for_model(
                        &trc,
                        &Default::default(),
                        model,
                        None,
                        crate::common::Columns::ForModel,
                    )?);
                }
                "write" => {
                    let (Some(long), Some(fit)) = (&long, &long_fit) else {
                        unreachable!("built above")
                    };
                    let table = crate::ik_cmd::angles_table(model, long, fit);
                    std::hint::black_box(jointfit_io::sto::format_sto(&table)?);
                }
                other => {
                    bail!("--profile {other}: expected ik, checked, before, after, read or write")
                }
            }
            let s = t.elapsed().as_secs_f64();
            best = best.min(s);
            println!("{part}: {:.3} ms", s * 1e3);
        }
        Ok(())
    })();
    drop(scratch);
    result?;
    println!("fastest of {repeat}: {:.3} ms", best * 1e3);
    Ok(())
}
