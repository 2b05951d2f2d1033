//! The exported C functions called directly, as a host calls them.

use std::ffi::{c_int, c_uint, c_void, CString};

use super::ffi::*;
use super::variables::{Kind, VARIABLES};
use crate::closed_loop::controller::{CommandDelay, Pid};
use crate::closed_loop::{run_closed_loop, Amplifier, CompensationMode, RunOptions};
use crate::scenario::Scenario;

const OK: c_int = 0;
const DISCARD: c_int = 2;
const ERROR: c_int = 3;

const VR_CURRENT: c_uint = 1;
const VR_VOLTAGE: c_uint = 2;
const VR_MOTOR_ANGLE: c_uint = 100;
const VR_OUTPUT_ANGLE: c_uint = 102;
const VR_MOTOR_ENCODER: c_uint = 104;
const VR_TENSION_UPPER: c_uint = 106;
const VR_TORQUE: c_uint = 108;
const VR_REGIME: c_uint = 110;
const VR_PRELOAD: c_uint = 1005;
const VR_BRAKE: c_uint = 1020;
const VR_BREAKAWAY: c_uint = 1021;
const VR_COUNTS: c_uint = 1080;
const VR_CABLE_MODEL: c_uint = 1101;

/// The resolved scenario in a resources folder, as export-fmu packs it.
struct Resources {
    _dir: tempfile::TempDir,
    uri: CString,
    guid: CString,
}

fn resources(scenario: &Scenario) -> Resources {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let text = scenario.to_toml();
    // A space in the path checks the URI decoding on the way.
    let res = dir.path().join("fmu resources");
    std::fs::create_dir(&res).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(res.join(super::SCENARIO_RESOURCE), &text).unwrap_or_else(|e| panic!("{e}"));
    let uri = format!("file://{}", res.display()).replace(' ', "%20");
    Resources {
        uri: CString::new(uri).unwrap_or_default(),
        guid: CString::new(super::guid(&text)).unwrap_or_default(),
        _dir: dir,
    }
}

fn scenario(set: &[&str]) -> Scenario {
    let text = crate::scenario::builtin("eots_tracking").unwrap_or_default();
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    Scenario::from_toml(text, "eots_tracking", "eots_tracking", &set)
        .unwrap_or_else(|e| panic!("{e}"))
}

struct Fmu {
    c: *mut c_void,
}

impl Fmu {
    fn new(r: &Resources) -> Self {
        let name = CString::new("test").unwrap_or_default();
        // SAFETY: valid strings; no callback structure.
        let c = unsafe {
            fmi2Instantiate(
                name.as_ptr(),
                1,
                r.guid.as_ptr(),
                r.uri.as_ptr(),
                std::ptr::null(),
                0,
                0,
            )
        };
        assert!(!c.is_null(), "instantiation failed");
        Fmu { c }
    }

    fn initialised(r: &Resources) -> Self {
        let f = Fmu::new(r);
        f.ok(unsafe { fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0) });
        f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
        f.ok(unsafe { fmi2ExitInitializationMode(f.c) });
        f
    }

    fn message(&self) -> String {
        unsafe { last_message(self.c) }.unwrap_or_default()
    }

    fn ok(&self, status: c_int) {
        assert_eq!(status, OK, "{}", self.message());
    }

    fn set(&self, vr: c_uint, v: f64) -> c_int {
        unsafe { fmi2SetReal(self.c, &vr, 1, &v) }
    }

    fn get(&self, vr: c_uint) -> f64 {
        let mut v = f64::NAN;
        self.ok(unsafe { fmi2GetReal(self.c, &vr, 1, &mut v) });
        v
    }

    fn get_int(&self, vr: c_uint) -> c_int {
        let mut v = -1;
        self.ok(unsafe { fmi2GetInteger(self.c, &vr, 1, &mut v) });
        v
    }

    fn step(&self, t: f64, h: f64) -> c_int {
        unsafe { fmi2DoStep(self.c, t, h, 1) }
    }

    /// `n` steps of `h` from `t0` with command `u`; the outputs after each.
    fn run(&self, t0: f64, h: f64, u: f64, n: usize) -> Vec<[f64; 4]> {
        self.ok(self.set(VR_CURRENT, u));
        (0..n)
            .map(|k| {
                self.ok(self.step(t0 + k as f64 * h, h));
                [
                    self.get(VR_MOTOR_ANGLE),
                    self.get(VR_OUTPUT_ANGLE),
                    self.get(VR_TENSION_UPPER),
                    self.get(VR_TORQUE),
                ]
            })
            .collect()
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        unsafe { fmi2FreeInstance(self.c) };
    }
}

#[test]
fn negative_preload_is_refused_at_initialisation_and_can_be_corrected() {
    let r = resources(&scenario(&[]));
    let f = Fmu::new(&r);
    f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
    // Accepted when set, checked at the end of initialisation.
    f.ok(f.set(VR_PRELOAD, -5.0));
    assert_eq!(f.get(VR_PRELOAD), -5.0);
    assert_eq!(unsafe { fmi2ExitInitializationMode(f.c) }, ERROR);
    let m = f.message();
    assert!(
        m.contains("drive.preload_n") && m.contains("-5") && m.contains("> 0"),
        "{m}"
    );
    // Still in initialisation: a good value lets it start.
    f.ok(f.set(VR_PRELOAD, 80.0));
    f.ok(unsafe { fmi2ExitInitializationMode(f.c) });
    assert_eq!(f.get(VR_PRELOAD), 80.0);
    assert_eq!(f.get(VR_TENSION_UPPER), 80.0);
}

#[test]
fn inconsistent_parameters_are_named() {
    let r = resources(&scenario(&[]));
    for (vr, v, key) in [
        (VR_BREAKAWAY, 0.5, "brake_breakaway_nm"),
        (VR_BRAKE, f64::NAN, "load.brake_nm"),
        (1102, 1e-2, "solver.max_step_s"),
        (1101, 7.0, "cable.model"),
    ] {
        let f = Fmu::new(&r);
        f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
        let set = f.set(vr, v);
        let status = if set == OK {
            unsafe { fmi2ExitInitializationMode(f.c) }
        } else {
            set
        };
        assert_eq!(status, ERROR, "{key}");
        assert!(f.message().contains(key), "{key}: {}", f.message());
    }
    // Integers go through fmi2SetInteger; a Real call on them is refused.
    let f = Fmu::new(&r);
    assert_eq!(f.set(VR_COUNTS, 4096.0), ERROR);
    assert!(f.message().contains("Integer"), "{}", f.message());
    let bad: c_int = 2;
    assert_eq!(unsafe { fmi2SetInteger(f.c, &VR_COUNTS, 1, &bad) }, OK);
    f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
    assert_eq!(unsafe { fmi2ExitInitializationMode(f.c) }, ERROR);
    assert!(
        f.message().contains("sensors.motor_counts_per_rev"),
        "{}",
        f.message()
    );
}

#[test]
fn bad_step_sizes_are_refused_and_the_instance_goes_on() {
    let r = resources(&scenario(&[]));
    let f = Fmu::initialised(&r);
    for h in [0.0, -1e-4, f64::NAN, f64::INFINITY] {
        assert_eq!(f.step(0.0, h), ERROR, "h = {h}");
        assert!(f.message().contains("step size"), "{}", f.message());
    }
    // A communication point that is not the FMU's time.
    assert_eq!(f.step(0.5, 1e-4), ERROR);
    assert!(f.message().contains("t = 0 s"), "{}", f.message());
    f.ok(f.step(0.0, 1e-4));
    f.ok(f.step(1e-4, 1e-4));
}

#[test]
fn calls_out_of_order_are_refused() {
    let r = resources(&scenario(&[]));
    let f = Fmu::new(&r);
    let mut v = 0.0;
    assert_eq!(f.step(0.0, 1e-4), ERROR);
    assert!(f.message().contains("not allowed"), "{}", f.message());
    assert_eq!(
        unsafe { fmi2GetReal(f.c, &VR_MOTOR_ANGLE, 1, &mut v) },
        ERROR
    );
    assert_eq!(unsafe { fmi2ExitInitializationMode(f.c) }, ERROR);
    assert_eq!(unsafe { fmi2Terminate(f.c) }, ERROR);
    f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
    assert_eq!(
        unsafe { fmi2SetupExperiment(f.c, 0, 0.0, 0.0, 0, 0.0) },
        ERROR
    );
    assert_eq!(unsafe { fmi2EnterInitializationMode(f.c) }, ERROR);
    f.ok(unsafe { fmi2ExitInitializationMode(f.c) });
    // Parameters are fixed after initialisation; outputs are never set.
    assert_eq!(f.set(VR_PRELOAD, 90.0), ERROR);
    assert!(f.message().contains("drive.preload_n"), "{}", f.message());
    assert_eq!(f.set(VR_MOTOR_ANGLE, 1.0), ERROR);
    assert!(f.message().contains("output"), "{}", f.message());
    // Unknown references and the other amplifier's input.
    assert_eq!(f.set(9999, 1.0), ERROR);
    assert_eq!(f.set(VR_VOLTAGE, 1.0), ERROR);
    assert!(f.message().contains("amplifier"), "{}", f.message());
    f.ok(f.step(0.0, 1e-4));
    f.ok(unsafe { fmi2Terminate(f.c) });
    assert_eq!(f.step(1e-4, 1e-4), ERROR);
    // A null instance is an error, not a crash.
    assert_eq!(
        unsafe { fmi2DoStep(std::ptr::null_mut(), 0.0, 1e-4, 1) },
        ERROR
    );
    // Reset brings back the defaults and the first phase.
    f.ok(unsafe { fmi2Reset(f.c) });
    f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
    f.ok(unsafe { fmi2ExitInitializationMode(f.c) });
    f.ok(f.step(0.0, 1e-4));
}

#[test]
fn unsupported_functions_answer_error() {
    let r = resources(&scenario(&[]));
    let f = Fmu::initialised(&r);
    let mut size = 0usize;
    assert_eq!(
        unsafe { fmi2SerializedFMUstateSize(f.c, std::ptr::null_mut(), &mut size) },
        ERROR
    );
    assert_eq!(unsafe { fmi2CancelStep(f.c) }, ERROR);
    let order: c_int = 1;
    let v = 0.0;
    assert_eq!(
        unsafe { fmi2SetRealInputDerivatives(f.c, &VR_CURRENT, 1, &order, &v) },
        ERROR
    );
    let mut t = -1.0;
    f.ok(unsafe { fmi2GetRealStatus(f.c, 2, &mut t) });
    assert_eq!(t, 0.0);
}

#[test]
fn instantiation_checks_type_guid_and_resources() {
    let r = resources(&scenario(&[]));
    let name = CString::new("x").unwrap_or_default();
    let other = CString::new("{00000000-0000-0000-0000-000000000000}").unwrap_or_default();
    let nowhere = CString::new("file:///nonexistent/resources").unwrap_or_default();
    unsafe {
        // Model Exchange.
        let c = fmi2Instantiate(
            name.as_ptr(),
            0,
            r.guid.as_ptr(),
            r.uri.as_ptr(),
            std::ptr::null(),
            0,
            0,
        );
        assert!(c.is_null());
        let c = fmi2Instantiate(
            name.as_ptr(),
            1,
            other.as_ptr(),
            r.uri.as_ptr(),
            std::ptr::null(),
            0,
            0,
        );
        assert!(c.is_null());
        let c = fmi2Instantiate(
            name.as_ptr(),
            1,
            r.guid.as_ptr(),
            nowhere.as_ptr(),
            std::ptr::null(),
            0,
            0,
        );
        assert!(c.is_null());
        let c = fmi2Instantiate(
            name.as_ptr(),
            1,
            r.guid.as_ptr(),
            std::ptr::null(),
            std::ptr::null(),
            0,
            0,
        );
        assert!(c.is_null());
    }
}

#[test]
fn two_instances_do_not_share_state() {
    let r = resources(&scenario(&[]));
    let h = 1e-4;
    let alone_a = Fmu::initialised(&r).run(0.0, h, 2.0, 200);
    let alone_b = Fmu::initialised(&r).run(0.0, h, -1.0, 200);
    assert_ne!(alone_a, alone_b);
    let a = Fmu::initialised(&r);
    let b = Fmu::initialised(&r);
    a.ok(a.set(VR_CURRENT, 2.0));
    b.ok(b.set(VR_CURRENT, -1.0));
    for k in 0..200 {
        let t = k as f64 * h;
        a.ok(a.step(t, h));
        b.ok(b.step(t, h));
        assert_eq!(a.get(VR_MOTOR_ANGLE), alone_a[k][0]);
        assert_eq!(b.get(VR_MOTOR_ANGLE), alone_b[k][0]);
        assert_eq!(b.get(VR_TORQUE), alone_b[k][3]);
    }
}

#[test]
fn a_hundred_instantiate_run_free_cycles() {
    let r = resources(&scenario(&[]));
    let first = Fmu::initialised(&r).run(0.0, 1e-4, 1.0, 20);
    for _ in 0..100 {
        let f = Fmu::initialised(&r);
        assert_eq!(f.run(0.0, 1e-4, 1.0, 20), first);
        f.ok(unsafe { fmi2Terminate(f.c) });
    }
}

#[test]
fn saved_state_replays_exactly() {
    let r = resources(&scenario(&[]));
    let f = Fmu::initialised(&r);
    let h = 1e-4;
    f.run(0.0, h, 3.0, 300);
    let mut state: *mut c_void = std::ptr::null_mut();
    f.ok(unsafe { fmi2GetFMUstate(f.c, &mut state) });
    let t0 = 300.0 * h;
    let first = f.run(t0, h, -3.0, 300);
    f.ok(unsafe { fmi2SetFMUstate(f.c, state) });
    let again = f.run(t0, h, -3.0, 300);
    assert_eq!(first, again);
    // Overwriting a saved state in place, then freeing it.
    f.ok(unsafe { fmi2GetFMUstate(f.c, &mut state) });
    f.ok(unsafe { fmi2FreeFMUstate(f.c, &mut state) });
    assert!(state.is_null());
}

#[test]
fn slack_and_gross_slip_end_the_run_with_discard_time_and_cause() {
    // 3 N of preload cannot carry the 1.6 N m of 8 A through a 0.1 m drum: the capstan
    // cable slides round the pulley first, the linear one (no friction) goes slack.
    let r = resources(&scenario(&["drive.preload_n=3.0"]));
    for (model, regime, cause) in [(0, 3, "gross slip"), (2, 2, "slack")] {
        let f = Fmu::new(&r);
        f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
        f.ok(unsafe { fmi2SetInteger(f.c, &VR_CABLE_MODEL, 1, &model) });
        f.ok(unsafe { fmi2ExitInitializationMode(f.c) });
        f.ok(f.set(VR_CURRENT, 8.0));
        let h = 1e-4;
        let mut status = OK;
        let mut k = 0;
        while status == OK && k < 20_000 {
            status = f.step(k as f64 * h, h);
            k += 1;
        }
        assert_eq!(status, DISCARD, "{}", f.message());
        let m = f.message();
        assert!(m.contains(cause) && m.contains("t = "), "{m}");
        assert_eq!(f.get_int(VR_REGIME), regime);
        let mut t = -1.0;
        f.ok(unsafe { fmi2GetRealStatus(f.c, 2, &mut t) });
        assert!((t - (k - 1) as f64 * h).abs() < 1e-12, "{t}");
        let mut terminated = 0;
        f.ok(unsafe { fmi2GetBooleanStatus(f.c, 3, &mut terminated) });
        assert_eq!(terminated, 1);
        // A further step is refused with the cause; the host may terminate and free.
        assert_eq!(f.step(t, h), ERROR);
        assert!(f.message().contains(cause), "{}", f.message());
        f.ok(unsafe { fmi2Terminate(f.c) });
    }
}

/// Reads `v` through the FMI getter of its type (integers and booleans as `f64`); the
/// destination starts as a value no getter gives, so a read that writes nothing shows.
fn read(f: &Fmu, v: &super::variables::Variable) -> f64 {
    let mut x = f64::NAN;
    let mut i: c_int = c_int::MIN;
    let status = unsafe {
        match v.kind {
            Kind::Real => fmi2GetReal(f.c, &v.vr, 1, &mut x),
            Kind::Integer => fmi2GetInteger(f.c, &v.vr, 1, &mut i),
            Kind::Boolean => fmi2GetBoolean(f.c, &v.vr, 1, &mut i),
        }
    };
    assert_eq!(status, OK, "{}: {}", v.name, f.message());
    match v.kind {
        Kind::Real => x,
        Kind::Integer | Kind::Boolean => {
            assert_ne!(i, c_int::MIN, "{}: nothing read", v.name);
            f64::from(i)
        }
    }
}

/// After initialisation and a step at rest every variable reads through the getter of its
/// type: each parameter gives the scenario's value (eots_tracking: encoders of 2^20 and 2^23
/// counts, whole counts, seed 1, the hysteretic cable as model 0), each output a finite
/// number, the regime contact (0).
#[test]
fn every_variable_reads_after_initialisation() {
    let s = scenario(&[]);
    let r = resources(&s);
    let f = Fmu::initialised(&r);
    f.ok(f.step(0.0, 1e-4));
    let defaults = super::variables::Values {
        params: super::instance::plant_params(&s).unwrap_or_else(|e| panic!("{e}")),
        inputs: Default::default(),
        outputs: Default::default(),
    };
    let known: [(c_uint, f64); 6] = [
        (VR_COUNTS, 1048576.0),
        (1081, 8388608.0),
        (1084, 1.0),
        (1085, 1.0),
        (VR_CABLE_MODEL, 0.0),
        (VR_REGIME, 0.0),
    ];
    let mut names = std::collections::HashSet::new();
    let mut integers_and_booleans = 0;
    for v in VARIABLES.iter().filter(|v| v.present(Amplifier::Current)) {
        assert!(names.insert(v.name), "{} twice", v.name);
        let x = read(&f, v);
        assert!(x.is_finite(), "{} = {x}", v.name);
        if v.causality == super::variables::Causality::Parameter {
            assert_eq!(
                x,
                (v.get)(&defaults),
                "{}: not the scenario's value",
                v.name
            );
        }
        if let Some((_, want)) = known.iter().find(|(vr, _)| *vr == v.vr) {
            assert_eq!(x, *want, "{}", v.name);
        }
        if v.kind != Kind::Real {
            integers_and_booleans += 1;
        }
    }
    assert_eq!(integers_and_booleans, known.len());
}

/// Integer and boolean parameters set through the FMI setters of their type read back
/// unchanged, in initialisation mode and after it.
#[test]
fn integer_and_boolean_parameters_round_trip() {
    let r = resources(&scenario(&[]));
    let f = Fmu::new(&r);
    f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
    // Values other than the scenario's (see every_variable_reads_after_initialisation).
    let set: [(c_uint, Kind, c_int); 5] = [
        (VR_COUNTS, Kind::Integer, 4096),
        (1081, Kind::Integer, 65536),
        (1084, Kind::Boolean, 0),
        (1085, Kind::Integer, 7),
        (VR_CABLE_MODEL, Kind::Integer, 2),
    ];
    for (vr, kind, x) in set {
        f.ok(unsafe {
            match kind {
                Kind::Integer => fmi2SetInteger(f.c, &vr, 1, &x),
                _ => fmi2SetBoolean(f.c, &vr, 1, &x),
            }
        });
    }
    let check = |when: &str| {
        for (vr, _, x) in set {
            let v = super::variables::find(vr, Amplifier::Current).expect("variable");
            assert_eq!(read(&f, v), f64::from(x), "{} {when}", v.name);
        }
    };
    check("in initialisation mode");
    f.ok(unsafe { fmi2ExitInitializationMode(f.c) });
    check("after initialisation");
    f.ok(f.step(0.0, 1e-4));
    check("after a step");
}

/// With the voltage amplifier the winding obeys `L di/dt = V - R i - ke w`; eots_tracking's
/// motor has R = 2 ohm, L = 1 mH (L/R = 0.5 ms) and ke = Kt = 0.2 V s/rad. The current
/// settles on `(V - ke w)/R` through the lag L/R, while the motor speed `w` keeps moving
/// (the rotor swings on the cable). Taking `w` from the FMU at every 0.1 ms step and
/// linear in between, the winding equation is solved exactly step by step; a linear input
/// is off the true `w` by at most `h^2/8 max|w''|` within a step, and the lag (a unit-gain
/// low-pass) passes at most `ke/R` times that to the current, so the FMU's current must lie
/// within `(ke/R) max|w_(k+1) - 2 w_k + w_(k-1)| / 8` of the solution (the RK4 error of
/// the plant adds far less). Against `(V - ke w)/R` itself the current lags by at most
/// `(L/R)(ke/R) max|dw/dt|` (the lag of a unit-gain first-order filter behind an input
/// moving at most that fast), taken over the last 2.5 ms (5 L/R), plus what is left of the
/// start-up after 20 L/R, `(V/R) e^-20`.
#[test]
fn voltage_amplifier_takes_the_voltage_input() {
    let r = resources(&scenario(&["closed_loop.motor.amplifier=\"voltage\""]));
    let f = Fmu::initialised(&r);
    assert_eq!(f.set(VR_CURRENT, 1.0), ERROR);
    f.ok(f.set(VR_VOLTAGE, 10.0));
    let (r_ohm, l_h, ke) = (f.get(1040), f.get(1041), f.get(1043));
    assert_eq!((r_ohm, l_h, ke), (2.0, 1e-3, 0.2));
    let (v, h, tau) = (10.0, 1e-4, l_h / r_ohm);
    let decay = (-h / tau).exp();
    let mut w = vec![f.get(101)];
    // The winding starts without current, the rotor at rest.
    let mut i = f.get(111);
    assert_eq!((i, w[0]), (0.0, 0.0));
    let mut worst = 0.0f64;
    for k in 0..100 {
        f.ok(f.step(k as f64 * h, h));
        w.push(f.get(101));
        let (u0, u1) = ((v - ke * w[k]) / r_ohm, (v - ke * w[k + 1]) / r_ohm);
        let slope = (u1 - u0) / h;
        i = u1 - tau * slope + (i - u0 + tau * slope) * decay;
        worst = worst.max((f.get(111) - i).abs());
    }
    let curvature = w
        .windows(3)
        .map(|x| (x[2] - 2.0 * x[1] + x[0]).abs())
        .fold(0.0, f64::max);
    let bound = ke / r_ohm * curvature / 8.0;
    let got = f.get(111);
    let settled = (v - ke * w[100]) / r_ohm;
    let fastest = w[75..]
        .windows(2)
        .map(|x| ((x[1] - x[0]) / h).abs())
        .fold(0.0, f64::max);
    let lag_bound = tau * ke / r_ohm * fastest + v / r_ohm * (-20.0f64).exp();
    println!("i {got} A, solved {i} A, (V - ke w)/R {settled} A; worst {worst} A, bound {bound} A; lag {} A, bound {lag_bound} A", (got - settled).abs());
    assert!(worst <= bound, "{worst} A off, bound {bound} A");
    assert!(
        (got - settled).abs() <= lag_bound,
        "{got} A against (V - ke w)/R = {settled} A, bound {lag_bound} A"
    );
}

#[test]
fn resource_uri_forms() {
    assert_eq!(
        uri_to_path("file:///data/a%20b/resources").ok(),
        Some("/data/a b/resources".into())
    );
    assert_eq!(uri_to_path("file://localhost/x").ok(), Some("/x".into()));
    assert_eq!(uri_to_path("file:/x").ok(), Some("/x".into()));
    assert!(uri_to_path("http://x/y").is_err());
    assert!(uri_to_path("file://elsewhere/x").is_err());
}

/// The project's own PID around the FMU gives the native closed loop bit for bit: the
/// FMU's step is the loop's period.
#[test]
fn project_pid_around_the_fmu_reproduces_the_native_run() {
    let s = scenario(&[
        "closed_loop.duration_s=1.0",
        "closed_loop.metrics_start_s=0.2",
        "closed_loop.modes=[\"none\"]",
        "closed_loop.timeseries_rate_hz=20000",
    ]);
    let native = run_closed_loop(&s, &RunOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let series = native.modes[0].series.clone().unwrap_or_default();
    assert_eq!(native.modes[0].mode, CompensationMode::None);
    let p = s
        .closed_loop
        .clone()
        .unwrap_or_else(|| panic!("closed loop"));
    let c = &p.controller;
    let ic = s.drive.ratio();
    let ts = 1.0 / c.sample_rate_hz;
    let n = p.periods() as usize;
    let r = resources(&s);
    let f = Fmu::initialised(&r);
    let mut pid = Pid::new(c, p.motor.command_limit());
    // The host applies the command after the controller's computation delay (whole periods
    // here: one FMU step per period).
    assert_eq!(c.computation_delay_samples.fract(), 0.0);
    let mut delay = CommandDelay::new(c.computation_delay_samples);
    for k in 0..=n {
        let t = k as f64 * ts;
        assert_eq!(
            f.get(VR_OUTPUT_ANGLE),
            series.output_angle_rad[k],
            "t = {t}"
        );
        assert_eq!(f.get(VR_MOTOR_ANGLE), series.motor_angle_rad[k], "t = {t}");
        let rp = p.reference.at(t);
        let u_ff =
            c.velocity_feedforward * (ic * rp.rate) + c.acceleration_feedforward * ic * rp.accel;
        let u = pid.update(ic * rp.value, f.get(VR_MOTOR_ENCODER), u_ff);
        assert_eq!(u, series.motor_command[k], "t = {t}");
        let held = delay.push(u).second;
        if k < n {
            f.ok(f.set(VR_CURRENT, held));
            f.ok(f.step(t, ts));
        }
    }
}

#[test]
fn guid_is_a_uuid_that_depends_on_the_text() {
    let g = super::guid("a = 1");
    assert_eq!(g.len(), 38, "{g}");
    assert!(g.starts_with('{') && g.ends_with('}'));
    let parts: Vec<usize> = g[1..37].split('-').map(str::len).collect();
    assert_eq!(parts, [8, 4, 4, 4, 12]);
    assert_eq!(g, super::guid("a = 1"));
    assert_ne!(g, super::guid("a = 2"));
}

#[test]
fn memoryless_cable_runs_and_reports_slip() {
    let r = resources(&scenario(&[]));
    let f = Fmu::new(&r);
    f.ok(unsafe { fmi2EnterInitializationMode(f.c) });
    let memoryless: c_int = 1;
    f.ok(unsafe { fmi2SetInteger(f.c, &VR_CABLE_MODEL, 1, &memoryless) });
    f.ok(f.set(VR_PRELOAD, 90.0));
    // Outputs before the end of initialisation: the plant at rest with the new preload.
    assert_eq!(f.get(VR_TENSION_UPPER), 90.0);
    f.ok(unsafe { fmi2ExitInitializationMode(f.c) });
    assert_eq!(f.get_int(VR_REGIME), 0);
    // 1 A winds the cable up against the held drum: slip zones grow on the wraps.
    f.run(0.0, 1e-4, 1.0, 200);
    assert_eq!(f.get_int(VR_REGIME), 1);
    assert!(f.get(VR_TORQUE) > 0.1, "{}", f.get(VR_TORQUE));
}

/// The co-simulation plant's output is the drum: a scenario whose `[effects]` put a jaw
/// link behind it is refused before export, naming the keys.
#[test]
fn a_jaw_link_behind_the_drum_is_refused_by_name() {
    let text = crate::scenario::builtin("davinci_tool4_loop").unwrap_or_default();
    let s = Scenario::from_toml(text, "davinci_tool4_loop", "davinci_tool4_loop", &[])
        .unwrap_or_else(|e| panic!("{e}"));
    let instance = super::instance::Instance::new(&s).unwrap_or_else(|e| panic!("{e}"));
    let m = instance.check_defaults().unwrap_err();
    assert!(
        m.contains("effects.load_compliance") && m.contains("friction_memory"),
        "{m}"
    );
}

#[test]
fn a_scenario_whose_loop_parts_the_fmu_would_drop_is_refused_naming_them() {
    let gimbal = Scenario::load("gimbal_stabilized", &[]).unwrap_or_else(|e| panic!("{e}"));
    let err = match super::instance::plant_params(&gimbal) {
        Ok(_) => panic!("gimbal_stabilized exported"),
        Err(e) => e,
    };
    for key in [
        "closed_loop.base_motion",
        "closed_loop.gyro",
        "closed_loop.controller.rate_loop",
        "closed_loop.controller.command_filters",
    ] {
        assert!(err.contains(key), "{key} not named: {err}");
    }
    let eots = Scenario::load("eots_tracking", &[]).unwrap_or_else(|e| panic!("{e}"));
    let p = super::instance::plant_params(&eots).unwrap_or_else(|e| panic!("{e}"));
    let values = super::variables::Values {
        params: p,
        inputs: Default::default(),
        outputs: Default::default(),
    };
    let xml = super::export::model_description(&eots, &values, "{guid}");
    assert!(xml.contains("description=\"Cable-drive gimbal plant of scenario eots_tracking"));
    for absent in ["gyro", "base motion", "rate loop", "filter", "20 kHz"] {
        let head = xml.lines().nth(1).unwrap_or_default();
        assert!(!head.contains(absent), "{absent} in {head}");
    }
}

#[test]
fn a_library_that_is_not_a_shared_object_is_refused_and_nothing_written() {
    use super::export::{export_fmu, ExportError};
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let eots = Scenario::load("eots_tracking", &[]).unwrap_or_else(|e| panic!("{e}"));
    let csv = dir.path().join("log.csv");
    std::fs::write(&csv, "t_s,theta_in_rad\n0,0\n").unwrap_or_else(|e| panic!("{e}"));
    let mut arm = b"\x7fELF\x02\x01\x01".to_vec();
    arm.resize(64, 0);
    arm[16] = 3; // a shared object, but for 64-bit ARM (183)
    arm[18] = 183;
    let arm_path = dir.path().join("libarm.so");
    std::fs::write(&arm_path, &arm).unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("drive.fmu");
    for (library, says) in [
        (csv, "no ELF header"),
        (dir.path().to_path_buf(), "a directory"),
        (arm_path, "another machine"),
    ] {
        match export_fmu(&eots, &library, &out, false) {
            Err(e @ ExportError::NotALibrary { .. }) => {
                let m = e.to_string();
                assert!(m.starts_with("--library") && m.contains(says), "{m}");
            }
            other => panic!("{}: {other:?}", library.display()),
        }
        assert!(!out.exists());
    }
}
