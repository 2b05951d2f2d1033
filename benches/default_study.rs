//! The default study end to end, as `cable-servo` with no arguments runs it: eots_tracking,
//! 3 modes x 20 s at 20 kHz, timeseries.csv, summary.json and the plots, into a fresh
//! results directory each time. See benches/README.md.

use cable_servo::run::{run_scenario, OutputOptions};
use cable_servo::scenario::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

fn bench(c: &mut Criterion) {
    let s = Scenario::load("eots_tracking", &[]).expect("built-in scenario");
    let tmp = tempfile::tempdir().expect("temporary directory");
    let mut k = 0u64;
    let mut group = c.benchmark_group("default_study");
    group.sample_size(10);
    group.bench_function("eots_tracking_3_modes_20s_csv_json_plots", |b| {
        b.iter(|| {
            k += 1;
            let out = OutputOptions {
                dir: tmp.path().join(format!("run-{k}")),
                force: false,
            };
            run_scenario(&s, &out).expect("the default study runs")
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
