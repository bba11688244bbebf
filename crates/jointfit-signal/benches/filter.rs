//! Throughput of the zero-phase Butterworth filter: one long signal, and a whole trial.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use jointfit::trial::Trial;
use jointfit_signal::LowPass;
use jointfit_signal::OrderConvention;
use jointfit_signal::{filter_trial, sosfiltfilt};
use nalgebra::Vector3;

fn signal(len: usize) -> Vec<f64> {
    (0..len)
        .map(|i| 0.5 + 0.05 * (i as f64 * 0.07).sin() + 0.002 * (i as f64 * 1.9).sin())
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("sosfiltfilt");
    let x = signal(100_000);
    g.throughput(Throughput::Elements(x.len() as u64));
    for (name, filter) in [
        ("effective4", LowPass::default()),
        (
            "design4",
            LowPass {
                convention: OrderConvention::Design,
                ..LowPass::default()
            },
        ),
    ] {
        let sos = filter.design(100.0).unwrap();
        g.bench_function(name, |b| b.iter(|| sosfiltfilt(&sos, &x).unwrap()));
    }
    g.finish();

    // 40 markers × 3000 frames with a gap every 500 frames.
    let (markers, frames) = (40, 3000);
    let positions = (0..frames)
        .flat_map(|f| {
            (0..markers).map(move |m| {
                if (f + 37 * m) % 500 < 5 {
                    Vector3::repeat(f64::NAN)
                } else {
                    let t = f as f64 * 0.01 + m as f64;
                    Vector3::new(t.sin(), t.cos(), 0.1 * (3.0 * t).sin())
                }
            })
        })
        .collect();
    let labels = (0..markers).map(|m| format!("M{m}")).collect();
    let trial = Trial::new(labels, 100.0, 1, positions).unwrap();
    let mut g = c.benchmark_group("filter_trial");
    g.throughput(Throughput::Elements((3 * markers * frames) as u64));
    g.bench_function("40x3000", |b| {
        b.iter(|| filter_trial(&trial, &LowPass::default()).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
