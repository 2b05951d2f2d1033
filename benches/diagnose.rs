//! Diagnosis of a 60 s log at 200 Hz (requirement: under 10 s).

use cable_servo::identify::{diagnose, synthesize, DiagnoseOptions, EffectName, SynthOptions};
use cable_servo::scenario::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

const SCENARIO: &str = r#"
name = "bench_ident"
study = "quasi_static"
[drive]
pulley_radius_m = 0.020
drum_radius_m = 0.1025
center_distance_m = 0.1450595
cable_modulus_n = 1.4e4
friction_coefficient = 0.2
preload_n = 50.0
drum_wrap_rad = 3.14159265
pulley_wrap_rad = 18.8495559
[load]
brake_nm = 0.7
unbalance_nm = 0.3
[quasi_static]
duration_s = 60.0
sample_rate_hz = 200.0
[quasi_static.motion]
kind = "sine"
amplitude_rad = 10.0
frequency_hz = 0.1
[identify]
unknown = ["cable_modulus_n", "preload_n", "friction_coefficient"]
"#;

fn bench(c: &mut Criterion) {
    let sc = Scenario::from_toml(SCENARIO, "bench", "bench", &[]).expect("scenario");
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
