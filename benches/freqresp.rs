//! Frequency response of `eots_tracking` on the hysteretic (memory) cable: 20 frequencies
//! from 1 Hz to 0.4 x Nyquist at 3 amplitudes at the plant input, margins refined, on
//! all cores. See benches/README.md.

use cable_servo::analysis::freqresp::{measure, FreqRespParams};
use cable_servo::closed_loop::ClosedLoopSource;
use cable_servo::scenario::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

fn bench(c: &mut Criterion) {
    let s = Scenario::load("eots_tracking", &[]).expect("built-in scenario");
    let setup = s.closed_loop_setup().expect("closed-loop scenario");
    let spec = FreqRespParams::default();
    let r = measure(setup, &spec, 0, &|| {}).expect("measurement");
    println!(
        "{} runs, {:.1} s simulated per measurement",
        r.runs, r.simulated_s
    );
    let mut group = c.benchmark_group("freqresp");
    group.sample_size(10);
    group.bench_function("eots_tracking_20f_x_3a_memory", |b| {
        b.iter(|| measure(setup, &spec, 0, &|| {}).expect("measurement"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
