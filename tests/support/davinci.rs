//! The eleven shipped da Vinci logs and the extension the leave-one-out table of
//! `docs/diagnose.md` uses, shared by `tests/real_data.rs` and `benches/leave_one_out.rs`.

use std::path::Path;

use cable_servo::identify::{BenchLog, EffectName};
use cable_servo::io::benchlog::read_bench_log;

/// Log names `tool4_NN.csv`: 0.1 Hz at seven jaw loads, then 60 % at four more rates.
pub const LOGS: [&str; 11] = [
    "00", "02", "04", "05", "06", "08", "09", "15", "25", "35", "45",
];

/// The multi-wrap extension of the leave-one-out table.
pub const EXTENSION: [EffectName; 3] = [
    EffectName::AngleDependentRatio,
    EffectName::LoadCompliance,
    EffectName::DistributedFrictionMemory,
];

/// The eleven logs from `dir`, in table order.
pub fn eleven_logs(dir: &Path) -> Vec<BenchLog> {
    LOGS.iter()
        .map(|k| {
            let p = dir.join(format!("tool4_{k}.csv"));
            read_bench_log(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        })
        .collect()
}
