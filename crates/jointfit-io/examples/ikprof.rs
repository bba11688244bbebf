// Scratch profiler (not committed).
use jointfit::ik::{seed_frame, solve_trial, IkOptions, IkWorkspace, MarkerMap};
use jointfit::landmarks::{personalize, MarkerSet, PersonalizeOptions};
use jointfit::model::lower_limb::Side;
use jointfit::model::Model;
use jointfit::residual_checks::{marker_offsets, offsets_of_fit};
use std::time::Instant;

fn min_time(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..reps {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
}

fn main() {
    let dir = std::path::PathBuf::from("/work/shared/data/opencap_expert1");
    let stat = jointfit_io::trial_file::read_trial(&dir.join("static1.trc")).unwrap();
    let set = MarkerSet::preset("opencap").unwrap();
    let subject = personalize(&stat, &set, Side::Right, &PersonalizeOptions::default()).unwrap();
    let model = Model::compile(&subject.spec).unwrap();
    let name = std::env::args().nth(1).unwrap_or("walking1".into());
    let trial = jointfit_io::trial_file::read_trial(&dir.join(format!("{name}.trc"))).unwrap();
    let p = model.nominal_params();
    let opts = IkOptions::default();
    let (map, _) = MarkerMap::allowing_absent(&model, trial.labels());
    let n = trial.n_frames() as f64;
    let reps = 300;
    let what = std::env::args().nth(2).unwrap_or_default();
    if what == "loop" {
        for _ in 0..20000 {
            std::hint::black_box(jointfit::workflow::ik_trial(&model, &p, &trial, &opts).unwrap());
        }
        return;
    }
    let t_ik = min_time(reps, || {
        std::hint::black_box(jointfit::workflow::ik_trial(&model, &p, &trial, &opts).unwrap());
    });
    let t_chk = min_time(reps, || {
        std::hint::black_box(jointfit::workflow::ik_checked(&model, &p, &trial, &opts));
    });
    let t_checks = min_time(reps, || {
        std::hint::black_box(jointfit::checks::check_trial(&model, &trial, &map));
    });
    let t_mo = min_time(reps, || {
        std::hint::black_box(marker_offsets(&model, &p, &trial, &map, &opts));
    });
    let fit = solve_trial(&model, &p, &trial, &map, &opts).unwrap();
    let t_of = min_time(reps, || {
        std::hint::black_box(offsets_of_fit(&model, &p, &trial, &map, &fit));
    });
    let mut ws = IkWorkspace::new(&model);
    let mut targets = Vec::new();
    map.targets(&trial, 0, &mut targets);
    let t_seed = min_time(reps, || {
        std::hint::black_box(seed_frame(&model, &p, &targets, &opts, &mut ws));
    });
    let its: usize = fit.frames.iter().map(|f| f.iterations).sum();
    println!("frames {n}, iterations/frame {:.2}", its as f64 / n);
    println!(
        "ik_trial      {:8.1} us  {:6.2} us/frame  {:7.0} fps",
        t_ik * 1e6,
        t_ik / n * 1e6,
        n / t_ik
    );
    println!(
        "ik_checked    {:8.1} us  {:6.2} us/frame  {:7.0} fps",
        t_chk * 1e6,
        t_chk / n * 1e6,
        n / t_chk
    );
    println!("check_trial   {:8.1} us", t_checks * 1e6);
    println!("marker_offsets{:8.1} us", t_mo * 1e6);
    println!("offsets_of_fit{:8.1} us", t_of * 1e6);
    println!("seed_frame    {:8.1} us", t_seed * 1e6);
}
