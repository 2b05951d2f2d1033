//! The margins of one loop on the verdict's grid: the loop gain at 4000 frequencies plus
//! the bisections of every crossing, as the verdict reads them at each operating point of
//! every case of a tolerance sweep. `eots_tracking` (4 states, plain PID) and
//! `gimbal_stabilized` (6 states, a rate loop with filters), each on the free span.

use cable_servo::analysis::linear::LinearLoop;
use cable_servo::analysis::verdict::MARGIN_POINTS;
use cable_servo::scenario::Scenario;
use criterion::{black_box, criterion_group, criterion_main, Criterion};

fn margins(c: &mut Criterion) {
    let mut group = c.benchmark_group("margins");
    for name in ["eots_tracking", "gimbal_stabilized"] {
        let s = Scenario::load(name, &[]).expect("built-in scenario");
        let p = s.closed_loop.as_ref().expect("a closed-loop scenario");
        let lin = LinearLoop::new(p, &s.drive);
        group.bench_function(name, |b| b.iter(|| black_box(&lin).margins(MARGIN_POINTS)));
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30);
    targets = margins
}
criterion_main!(benches);
