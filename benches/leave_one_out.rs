//! Joint calibration over the eleven da Vinci logs and the leave-one-log-out table
//! (requirement: under 60 s on 2 cores). The logs are read from `$CABLE_SERVO_DAVINCI`,
//! else `../shared/real-data/davinci` beside the repository; the bench says so and does
//! nothing when neither exists.

use std::path::{Path, PathBuf};

use cable_servo::identify::loo::leave_one_out;
use cable_servo::identify::startup::StartMode;
use cable_servo::scenario::Scenario;
use criterion::{criterion_group, criterion_main, Criterion};

#[path = "../tests/support/davinci.rs"]
mod davinci;
use davinci::{eleven_logs, EXTENSION};

fn data_dir() -> Option<PathBuf> {
    std::env::var_os("CABLE_SERVO_DAVINCI")
        .map(PathBuf::from)
        .into_iter()
        .chain([Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/real-data/davinci")])
        .find(|d| d.join("tool4_00.csv").exists())
}

fn bench(c: &mut Criterion) {
    let Some(dir) = data_dir() else {
        eprintln!("da Vinci logs not found (set CABLE_SERVO_DAVINCI); nothing measured");
        return;
    };
    let scenario = Scenario::load("scenarios/davinci_tool4.toml", &[]).expect("scenario");
    let ident = scenario.identify.clone().unwrap_or_default();
    let logs = eleven_logs(&dir);
    let mut group = c.benchmark_group("davinci_eleven_logs");
    group.sample_size(10);
    group.bench_function("joint_calibration_and_leave_one_out", |b| {
        b.iter(|| {
            leave_one_out(
                &scenario.drive,
                &ident,
                &logs,
                &EXTENSION,
                StartMode::Detect,
            )
            .expect("leave-one-out")
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
