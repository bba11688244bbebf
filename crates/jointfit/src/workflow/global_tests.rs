//! Tests of the global phase.

use super::super::synthetic_tests::synthetic;
use super::super::{calibrate, FitSettings, NoObserver};
use crate::calibrate::params_for_groups;
use crate::model::lower_limb::{lower_limb, Side};
use crate::model::Model;

/// The whole global phase on a trial long enough for every parallel pass this module
/// and [`crate::calibrate::Problem`] run (probes on every 8th frame, two seeded chunks of
/// starting coordinates, inner passes in tasks, a finishing solve of a probe that is not
/// the given start): the same bits on 1, 2 and 3 threads.
#[test]
fn global_phase_gives_the_same_bits_on_any_thread_count() {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let truth: Vec<f64> = model
        .parameters()
        .iter()
        .enumerate()
        .map(|(k, x)| x.nominal + 0.12 * (x.upper - x.lower) * (k as f64 * 1.7).sin())
        .collect();
    let trial = synthetic(&model, &truth, 200, 0.004);
    let free = params_for_groups(&model, &["all"]).unwrap();
    let start = model.nominal_params();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                calibrate(
                    &model,
                    &start,
                    &[&trial],
                    &free,
                    &FitSettings::default(),
                    &mut NoObserver,
                )
                .unwrap()
            })
    };
    let one = run(1);
    let g = one.global.clone().unwrap();
    assert_eq!(g.probe_frames, 25);
    assert!(g.finished.iter().any(|&k| k != 0), "{g:?}");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for threads in [2, 3] {
        let other = run(threads);
        assert_eq!(bits(&one.fit.p), bits(&other.fit.p), "{threads} threads");
        assert_eq!(one.cost_after.to_bits(), other.cost_after.to_bits());
        assert_eq!(one.cost_before.to_bits(), other.cost_before.to_bits());
        assert_eq!(one.global, other.global);
        for (a, b) in one.fit.coords.iter().zip(&other.fit.coords) {
            assert_eq!(bits(a), bits(b));
        }
    }
}
