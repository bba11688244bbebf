//! FK and both marker Jacobians of the 27-parameter leg model (target: ≤ 1 µs per evaluation).
//!
//! `cargo bench -p jointfit --bench kinematics`

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use jointfit::kinematics::{forward_kinematics, KinData, Want};
use jointfit::model::lower_limb::{lower_limb, Side};
use jointfit::model::Model;

fn leg(c: &mut Criterion) {
    let model = Model::compile(&lower_limb(Side::Right)).unwrap();
    let p = model.nominal_params();
    let q: Vec<f64> = (0..model.coordinates().len())
        .map(|i| 0.1 * i as f64 - 0.3)
        .collect();
    let mut data = KinData::new(&model);
    let mut group = c.benchmark_group("leg_model");
    for (name, want) in [
        ("fk", Want::Positions),
        ("fk+dq", Want::Dq),
        ("fk+dq+dp", Want::DqDp),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                forward_kinematics(&model, black_box(&p), black_box(&q), want, &mut data);
                black_box(&data.markers);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, leg);
criterion_main!(benches);
