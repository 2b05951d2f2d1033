//! Diagnosis of a 60 s log at 200 Hz (requirement: under 10 s).

use cable_servo::identify::{diagnose, synthesize, DiagnoseOptions, EffectName, SynthOptions};
use cable_servo::scenario::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

/// The built-in slewing-axis scenario, lengthened to 60 s at 200 Hz, with friction,
/// preload and modulus all calibrated (the heaviest diagnosis).
fn scenario() -> Scenario {
    let overrides = [
        "quasi_static.duration_s=60".to_string(),
        "quasi_static.sample_rate_hz=200".to_string(),
        r#"identify.unknown=["cable_modulus_n", "preload_n", "friction_coefficient"]"#.to_string(),
    ];
    Scenario::load("gimbal_ident", &overrides).expect("built-in scenario")
}

fn bench(c: &mut Criterion) {
    let sc = scenario();
    let log = synthesize(
        &sc,
        &[(EffectName::BearingFriction, 0.15)],
        1,
        &SynthOptions::default(),
    )
    .expect("synthesis");
    let mut g = c.benchmark_group("diagnose");
    g.sample_size(10);
    g.bench_function("60s_200Hz", |b| {
        b.iter(|| diagnose(&sc, std::slice::from_ref(&log), &DiagnoseOptions::default()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
