use cable_servo::closed_loop::*;
use cable_servo::scenario::Scenario;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("eots_tracking");
    let sets: Vec<String> = args[2.min(args.len())..].to_vec();
    let sc = Scenario::load(name, &sets).unwrap();
    let t = std::time::Instant::now();
    let r = run_closed_loop(&sc, &RunOptions::default()).unwrap();
    println!("wall {:?}", t.elapsed());
    print!("{}", format_table(&r));
    for m in &r.modes { println!("{} {:?} te_peak {:?} rms_i {:?} wall {:.3} steps {:?}", m.mode.name(), m.stats.rhs_evaluations, m.metrics.peak_transmission_error_mrad, m.metrics.rms_current_a, m.stats.wall_s, m.metrics.steps.iter().map(|s| s.settling_time_s).collect::<Vec<_>>()); }
    write_closed_loop_outputs(std::path::Path::new(&format!("/tmp/cl_{name}")), &sc, &r).unwrap();
}
