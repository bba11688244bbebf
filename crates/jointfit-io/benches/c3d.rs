//! C3D decoding throughput: the largest sample file (ezc3d's Vicon.c3d, 2.25 MB, 51 float
//! points × 580 frames + 38 analog channels at 2 kHz) parsed from memory.
//!
//! `JOINTFIT_DATA=… cargo bench -p jointfit-io --bench c3d`

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use jointfit_io::c3d::parse_c3d;
use jointfit_testkit::data_file;

fn bench(c: &mut Criterion) {
    let Some(path) = data_file("c3d_reader/ezc3d/Vicon.c3d") else {
        return;
    };
    let bytes = std::fs::read(&path).expect("read the sample");
    let mut g = c.benchmark_group("c3d");
    g.throughput(Throughput::Bytes(bytes.len() as u64));
    g.bench_function("parse Vicon.c3d", |b| {
        b.iter(|| parse_c3d(black_box(&bytes)).expect("parses"))
    });
    g.bench_function("parse + to_trial Vicon.c3d", |b| {
        b.iter(|| {
            parse_c3d(black_box(&bytes))
                .expect("parses")
                .to_trial()
                .expect("trial")
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
