//! The `fmi2*` C functions of the FMI 2.0 Co-Simulation interface, exported by the
//! shared library (`libcable_servo.so`, copied into the FMU as
//! `binaries/linux64/cable_servo.so`).
//!
//! Every function converts its arguments, calls [`Instance`] inside `catch_unwind` (a
//! panic becomes `fmi2Error` with a logged message and puts the instance in its error
//! phase; it never unwinds into the host) and passes the instance's messages to the host's
//! logger. Messages are passed as the logger's format string with `%` written out, so a
//! host that formats them and one that prints them raw show the same text.
//!
//! Functions this FMU does not support (directional derivatives, input interpolation,
//! serialised states, asynchronous steps) are exported and return `fmi2Error`.

#![allow(non_snake_case)]

use std::ffi::{c_char, c_int, c_uint, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

use super::instance::{FmuError, Instance, LogLine, Snapshot, Status, LOG_CATEGORIES};
use super::variables::Kind;
use crate::scenario::Scenario;

/// `fmi2Status` values.
const OK: c_int = Status::Ok as c_int;
const ERROR: c_int = Status::Error as c_int;

/// `fmi2Type` of a Co-Simulation instance.
const CO_SIMULATION: c_int = 1;

/// `fmi2StatusKind` values.
const DO_STEP_STATUS: c_int = 0;
const PENDING_STATUS: c_int = 1;
const LAST_SUCCESSFUL_TIME: c_int = 2;
const TERMINATED: c_int = 3;

/// `fmi2CallbackLogger`: `(environment, instance name, status, category, format, ...)`.
pub type Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char, ...);

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct CallbackFunctions {
    /// Logger (may be null: messages are then only kept for [`last_message`]).
    pub logger: Option<Logger>,
    /// Not used (`canNotUseMemoryManagementFunctions`).
    pub allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    /// Not used.
    pub free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    /// Not used (no asynchronous steps).
    pub step_finished: Option<unsafe extern "C" fn(*mut c_void, c_int)>,
    /// Passed back to the logger.
    pub component_environment: *mut c_void,
}

/// What an `fmi2Component` points to.
struct Component {
    instance: Instance,
    name: CString,
    logger: Option<Logger>,
    environment: *mut c_void,
    last_message: Option<String>,
}

/// Passes one message to the host's logger (nothing when there is none).
fn log_to(
    logger: Option<Logger>,
    environment: *mut c_void,
    name: &CStr,
    status: Status,
    category: &str,
    message: &str,
) {
    let Some(logger) = logger else { return };
    let text =
        CString::new(message.replace('%', " percent").replace('\0', " ")).unwrap_or_default();
    let category = CString::new(category).unwrap_or_default();
    // SAFETY: the logger came from the host's callback structure with this environment;
    // every string is NUL-terminated and outlives the call, and the format string holds
    // no conversion.
    unsafe {
        logger(
            environment,
            name.as_ptr(),
            status as c_int,
            category.as_ptr(),
            text.as_ptr(),
        );
    }
}

impl Component {
    fn emit(&mut self, line: &LogLine) {
        self.last_message = Some(line.message.clone());
        log_to(
            self.logger,
            self.environment,
            &self.name,
            line.status,
            line.category,
            &line.message,
        );
    }

    fn flush(&mut self) {
        let lines = std::mem::take(&mut self.instance.log);
        for line in &lines {
            self.emit(line);
        }
    }

    fn report(&mut self, call: &str, e: &FmuError) {
        let category = match e.status {
            Status::Discard => "logStatusDiscard",
            Status::Warning => "logStatusWarning",
            _ => "logStatusError",
        };
        self.emit(&LogLine {
            status: e.status,
            category,
            message: format!("{call}: {}", e.message),
        });
    }
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown cause".into())
}

/// Runs `f` on the instance behind `c`: panics caught, messages logged, status returned.
///
/// # Safety
/// `c` is null or a pointer returned by [`fmi2Instantiate`] and not yet freed.
unsafe fn with(
    c: *mut c_void,
    call: &str,
    f: impl FnOnce(&mut Instance) -> Result<(), FmuError>,
) -> c_int {
    if c.is_null() {
        return ERROR;
    }
    // SAFETY: per the contract above.
    let comp = unsafe { &mut *(c as *mut Component) };
    let result = catch_unwind(AssertUnwindSafe(|| f(&mut comp.instance)));
    comp.flush();
    match result {
        Ok(Ok(())) => OK,
        Ok(Err(e)) => {
            comp.report(call, &e);
            e.status as c_int
        }
        Err(p) => {
            comp.instance.break_down();
            let e = FmuError {
                status: Status::Error,
                message: format!(
                    "internal error ({}); the instance is unusable: fmi2FreeInstance or fmi2Reset it",
                    panic_text(p.as_ref())
                ),
            };
            comp.report(call, &e);
            ERROR
        }
    }
}

/// The text of the last message an instance logged (tests; hosts use the logger).
///
/// # Safety
/// `c` is null or a live pointer returned by [`fmi2Instantiate`].
pub unsafe fn last_message(c: *mut c_void) -> Option<String> {
    if c.is_null() {
        return None;
    }
    // SAFETY: per the contract above.
    unsafe { (*(c as *mut Component)).last_message.clone() }
}

/// A C string argument, `None` when null or not UTF-8.
///
/// # Safety
/// `s` is null or NUL-terminated.
unsafe fn text<'a>(s: *const c_char) -> Option<&'a str> {
    if s.is_null() {
        None
    } else {
        // SAFETY: per the contract above.
        unsafe { CStr::from_ptr(s) }.to_str().ok()
    }
}

/// Directory of a `file:` URI (`file:///a/b`, `file://localhost/a/b`, `file:/a/b`),
/// percent escapes decoded.
pub fn uri_to_path(uri: &str) -> Result<PathBuf, String> {
    let rest = uri.strip_prefix("file:").ok_or_else(|| {
        format!("fmuResourceLocation {uri}: expected a file: URI (file:///path/to/resources)")
    })?;
    let path = if let Some(r) = rest.strip_prefix("//") {
        let slash = r.find('/').unwrap_or(r.len());
        let host = &r[..slash];
        if !(host.is_empty() || host == "localhost") {
            return Err(format!(
                "fmuResourceLocation {uri}: host {host} is not this machine; extract the FMU to a local directory"
            ));
        }
        &r[slash..]
    } else {
        rest
    };
    let bytes = path.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).unwrap_or("");
            if let Ok(b) = u8::from_str_radix(hex, 16) {
                out.push(b);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    let s = String::from_utf8(out)
        .map_err(|_| format!("fmuResourceLocation {uri}: not UTF-8 once decoded"))?;
    Ok(PathBuf::from(s))
}

/// The scenario in the FMU's resources, checked against the GUID.
fn load_scenario(resources: Option<&str>, guid: Option<&str>) -> Result<Scenario, String> {
    let uri = resources.ok_or(
        "fmuResourceLocation is null: the FMU reads its defaults from resources/scenario.toml",
    )?;
    let path = uri_to_path(uri)?.join(super::SCENARIO_RESOURCE);
    let text = std::fs::read_to_string(&path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let expected = super::guid(&text);
    match guid {
        Some(g) if g == expected => {}
        other => {
            return Err(format!(
                "GUID {} does not match this FMU's ({expected}): modelDescription.xml, resources and binary come from different exports",
                other.unwrap_or("(null)")
            ))
        }
    }
    Scenario::from_toml(&text, &path.display().to_string(), "fmu", &[]).map_err(|e| e.to_string())
}

/// `fmi2GetTypesPlatform`.
#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

/// `fmi2GetVersion`.
#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// `fmi2Instantiate`: a Co-Simulation instance with the defaults of the scenario in
/// `fmuResourceLocation`/scenario.toml; null (with a logged reason) when it cannot be.
///
/// # Safety
/// Strings are null or NUL-terminated; `functions` is null or points to a valid
/// `fmi2CallbackFunctions` whose logger stays callable until `fmi2FreeInstance`.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: c_int,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    logging_on: c_int,
) -> *mut c_void {
    let result = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: per the contract above.
        let (logger, environment) = match unsafe { functions.as_ref() } {
            Some(f) => (f.logger, f.component_environment),
            None => (None, std::ptr::null_mut()),
        };
        // SAFETY: per the contract above.
        let name = unsafe { text(instance_name) }.unwrap_or("cable_servo");
        let cname = CString::new(name).unwrap_or_default();
        let fail = |message: String| {
            log_to(
                logger,
                environment,
                &cname,
                Status::Error,
                "logStatusError",
                &format!("fmi2Instantiate: {message}"),
            );
            std::ptr::null_mut::<c_void>()
        };
        if fmu_type != CO_SIMULATION {
            return fail(format!(
                "fmuType {fmu_type}: this FMU supports Co-Simulation (1) only"
            ));
        }
        // SAFETY: per the contract above.
        let scenario =
            match load_scenario(unsafe { text(resource_location) }, unsafe { text(guid) }) {
                Ok(s) => s,
                Err(m) => return fail(m),
            };
        let mut instance = match Instance::new(&scenario) {
            Ok(i) => i,
            Err(m) => return fail(m),
        };
        instance.log_events = logging_on != 0;
        let comp = Box::new(Component {
            instance,
            name: cname,
            logger,
            environment,
            last_message: None,
        });
        Box::into_raw(comp) as *mut c_void
    }));
    result.unwrap_or(std::ptr::null_mut())
}

/// `fmi2FreeInstance`.
///
/// # Safety
/// `c` is null or a pointer returned by [`fmi2Instantiate`], freed only once.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
    if !c.is_null() {
        // SAFETY: per the contract above.
        let comp = unsafe { Box::from_raw(c as *mut Component) };
        let _ = catch_unwind(AssertUnwindSafe(|| drop(comp)));
    }
}

/// `fmi2SetDebugLogging`: `logEvents` on or off (other categories are always logged).
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `categories` holds `n` NUL-terminated strings.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: *mut c_void,
    logging_on: c_int,
    n: usize,
    categories: *const *const c_char,
) -> c_int {
    unsafe {
        with(c, "fmi2SetDebugLogging", |inst| {
            if n > 0 && categories.is_null() {
                return Err(FmuError::error("null category array"));
            }
            // SAFETY: per the contract above.
            let names: Vec<String> = (0..n)
                .map(|i| {
                    text(*categories.add(i))
                        .map(str::to_string)
                        .ok_or_else(|| FmuError::error("a null or non-UTF-8 category"))
                })
                .collect::<Result<_, _>>()?;
            for n in &names {
                if !LOG_CATEGORIES.iter().any(|(c, _)| c == n) {
                    let known: Vec<&str> = LOG_CATEGORIES.iter().map(|c| c.0).collect();
                    return Err(FmuError::error(format!(
                        "unknown log category {n}; known: {}",
                        known.join(", ")
                    )));
                }
            }
            if names.is_empty() || names.iter().any(|n| n == "logEvents") {
                inst.log_events = logging_on != 0;
            }
            Ok(())
        })
    }
}

/// `fmi2SetupExperiment` (the tolerance is not used: fixed-step RK4).
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: *mut c_void,
    _tolerance_defined: c_int,
    _tolerance: f64,
    start_time: f64,
    stop_time_defined: c_int,
    stop_time: f64,
) -> c_int {
    unsafe {
        with(c, "fmi2SetupExperiment", |i| {
            i.setup_experiment(start_time, (stop_time_defined != 0).then_some(stop_time))
        })
    }
}

/// `fmi2EnterInitializationMode`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> c_int {
    unsafe {
        with(
            c,
            "fmi2EnterInitializationMode",
            Instance::enter_initialization,
        )
    }
}

/// `fmi2ExitInitializationMode`: parameters checked here.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> c_int {
    unsafe {
        with(
            c,
            "fmi2ExitInitializationMode",
            Instance::exit_initialization,
        )
    }
}

/// `fmi2Terminate`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> c_int {
    unsafe { with(c, "fmi2Terminate", Instance::terminate) }
}

/// `fmi2Reset`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> c_int {
    unsafe {
        with(c, "fmi2Reset", |i| {
            i.reset();
            Ok(())
        })
    }
}

/// Reads `n` values of kind `kind` into `out` through `put`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `out` hold `n` elements.
unsafe fn get_values<T>(
    c: *mut c_void,
    call: &str,
    vr: *const c_uint,
    n: usize,
    out: *mut T,
    kind: Kind,
    put: impl Fn(f64) -> T,
) -> c_int {
    unsafe {
        with(c, call, |i| {
            if n > 0 && (vr.is_null() || out.is_null()) {
                return Err(FmuError::error("null value reference or value array"));
            }
            for k in 0..n {
                let v = i.get(*vr.add(k), kind)?;
                *out.add(k) = put(v);
            }
            Ok(())
        })
    }
}

/// Writes `n` values of kind `kind` from `values` through `take`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `values` hold `n` elements.
unsafe fn set_values<T: Copy>(
    c: *mut c_void,
    call: &str,
    vr: *const c_uint,
    n: usize,
    values: *const T,
    kind: Kind,
    take: impl Fn(T) -> f64,
) -> c_int {
    unsafe {
        with(c, call, |i| {
            if n > 0 && (vr.is_null() || values.is_null()) {
                return Err(FmuError::error("null value reference or value array"));
            }
            for k in 0..n {
                i.set(*vr.add(k), kind, take(*values.add(k)))?;
            }
            Ok(())
        })
    }
}

/// `fmi2GetReal`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: *mut c_void,
    vr: *const c_uint,
    n: usize,
    value: *mut f64,
) -> c_int {
    unsafe { get_values(c, "fmi2GetReal", vr, n, value, Kind::Real, |v| v) }
}

/// `fmi2GetInteger`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: *mut c_void,
    vr: *const c_uint,
    n: usize,
    value: *mut c_int,
) -> c_int {
    unsafe {
        get_values(c, "fmi2GetInteger", vr, n, value, Kind::Integer, |v| {
            v as c_int
        })
    }
}

/// `fmi2GetBoolean`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: *mut c_void,
    vr: *const c_uint,
    n: usize,
    value: *mut c_int,
) -> c_int {
    unsafe {
        get_values(c, "fmi2GetBoolean", vr, n, value, Kind::Boolean, |v| {
            c_int::from(v != 0.0)
        })
    }
}

/// `fmi2GetString`: this FMU has no string variables.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: *mut c_void,
    _vr: *const c_uint,
    n: usize,
    _value: *mut *const c_char,
) -> c_int {
    unsafe { no_strings(c, "fmi2GetString", n) }
}

/// `fmi2SetReal`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: *mut c_void,
    vr: *const c_uint,
    n: usize,
    value: *const f64,
) -> c_int {
    unsafe { set_values(c, "fmi2SetReal", vr, n, value, Kind::Real, |v| v) }
}

/// `fmi2SetInteger`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: *mut c_void,
    vr: *const c_uint,
    n: usize,
    value: *const c_int,
) -> c_int {
    unsafe { set_values(c, "fmi2SetInteger", vr, n, value, Kind::Integer, f64::from) }
}

/// `fmi2SetBoolean`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `vr` and `value` hold `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: *mut c_void,
    vr: *const c_uint,
    n: usize,
    value: *const c_int,
) -> c_int {
    unsafe {
        set_values(c, "fmi2SetBoolean", vr, n, value, Kind::Boolean, |v| {
            f64::from(u8::from(v != 0))
        })
    }
}

/// `fmi2SetString`: this FMU has no string variables.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: *mut c_void,
    _vr: *const c_uint,
    n: usize,
    _value: *const *const c_char,
) -> c_int {
    unsafe { no_strings(c, "fmi2SetString", n) }
}

unsafe fn no_strings(c: *mut c_void, call: &str, n: usize) -> c_int {
    unsafe {
        with(c, call, |_| {
            if n == 0 {
                Ok(())
            } else {
                Err(FmuError::error("this FMU has no String variables"))
            }
        })
    }
}

/// `fmi2GetFMUstate`: a copy of the whole simulation state (plant, cable memory, brake,
/// encoder noise generator, inputs and outputs). A non-null `*state` from an earlier call
/// is overwritten in place.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `state` points to null or to a state from this
/// library not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    unsafe {
        with(c, "fmi2GetFMUstate", |i| {
            if state.is_null() {
                return Err(FmuError::error("null state pointer"));
            }
            let snap = i.snapshot()?;
            let old = *state as *mut Snapshot;
            if old.is_null() {
                *state = Box::into_raw(Box::new(snap)) as *mut c_void;
            } else {
                *old = snap;
            }
            Ok(())
        })
    }
}

/// `fmi2SetFMUstate`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `state` is null or a state from [`fmi2GetFMUstate`]
/// not yet freed.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, state: *mut c_void) -> c_int {
    unsafe {
        with(c, "fmi2SetFMUstate", |i| {
            match (state as *const Snapshot).as_ref() {
                Some(s) => i.restore(s),
                None => Err(FmuError::error("null FMU state")),
            }
        })
    }
}

/// `fmi2FreeFMUstate`.
///
/// # Safety
/// `state` points to null or to a state from [`fmi2GetFMUstate`] freed only once.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    unsafe {
        with(c, "fmi2FreeFMUstate", |_| {
            if !state.is_null() && !(*state).is_null() {
                drop(Box::from_raw(*state as *mut Snapshot));
                *state = std::ptr::null_mut();
            }
            Ok(())
        })
    }
}

unsafe fn unsupported(c: *mut c_void, call: &str, why: &str) -> c_int {
    let why = why.to_string();
    unsafe { with(c, call, move |_| Err(FmuError::error(why))) }
}

/// `fmi2SerializedFMUstateSize`: not supported (`canSerializeFMUstate = false`).
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: *mut c_void,
    _state: *mut c_void,
    _size: *mut usize,
) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2SerializedFMUstateSize",
            "serialised FMU states are not supported (canSerializeFMUstate = false)",
        )
    }
}

/// `fmi2SerializeFMUstate`: not supported.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: *mut c_void,
    _state: *mut c_void,
    _bytes: *mut c_char,
    _size: usize,
) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2SerializeFMUstate",
            "serialised FMU states are not supported (canSerializeFMUstate = false)",
        )
    }
}

/// `fmi2DeSerializeFMUstate`: not supported.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: *mut c_void,
    _bytes: *const c_char,
    _size: usize,
    _state: *mut *mut c_void,
) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2DeSerializeFMUstate",
            "serialised FMU states are not supported (canSerializeFMUstate = false)",
        )
    }
}

/// `fmi2GetDirectionalDerivative`: not supported.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: *mut c_void,
    _unknown: *const c_uint,
    _n_unknown: usize,
    _known: *const c_uint,
    _n_known: usize,
    _dv_known: *const f64,
    _dv_unknown: *mut f64,
) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2GetDirectionalDerivative",
            "directional derivatives are not provided (providesDirectionalDerivative = false)",
        )
    }
}

/// `fmi2SetRealInputDerivatives`: not supported (inputs are held over a step).
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: *mut c_void,
    _vr: *const c_uint,
    _n: usize,
    _order: *const c_int,
    _value: *const f64,
) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2SetRealInputDerivatives",
            "inputs are held over a step (canInterpolateInputs = false)",
        )
    }
}

/// `fmi2GetRealOutputDerivatives`: not supported.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: *mut c_void,
    _vr: *const c_uint,
    _n: usize,
    _order: *const c_int,
    _value: *mut f64,
) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2GetRealOutputDerivatives",
            "output derivatives are not provided (maxOutputDerivativeOrder = 0)",
        )
    }
}

/// `fmi2DoStep`: `Discard` when the plant stops (slack, gross slip, divergence), with
/// the time and cause logged.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: *mut c_void,
    current_communication_point: f64,
    communication_step_size: f64,
    _no_set_prior: c_int,
) -> c_int {
    unsafe {
        with(c, "fmi2DoStep", |i| {
            i.do_step(current_communication_point, communication_step_size)
        })
    }
}

/// `fmi2CancelStep`: steps are never asynchronous, so there is none to cancel.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2CancelStep",
            "steps are synchronous (canRunAsynchronuously = false): nothing to cancel",
        )
    }
}

/// `fmi2GetStatus`: only for asynchronous steps, which this FMU never runs.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: *mut c_void, kind: c_int, value: *mut c_int) -> c_int {
    unsafe {
        with(c, "fmi2GetStatus", |_| {
            if kind == DO_STEP_STATUS && !value.is_null() {
                // A step always returns its final status: nothing is pending.
                *value = OK;
                return Ok(());
            }
            Err(FmuError::error(format!(
                "status kind {kind} is not available from fmi2GetStatus"
            )))
        })
    }
}

/// `fmi2GetRealStatus`: `fmi2LastSuccessfulTime`.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `value` points to one `fmi2Real`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: *mut c_void, kind: c_int, value: *mut f64) -> c_int {
    unsafe {
        with(c, "fmi2GetRealStatus", |i| {
            if kind == LAST_SUCCESSFUL_TIME && !value.is_null() {
                *value = i.last_successful_time();
                Ok(())
            } else {
                Err(FmuError::error(format!(
                    "status kind {kind}: fmi2GetRealStatus answers fmi2LastSuccessfulTime (2) only"
                )))
            }
        })
    }
}

/// `fmi2GetIntegerStatus`: no integer status exists.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: *mut c_void,
    kind: c_int,
    _value: *mut c_int,
) -> c_int {
    unsafe {
        unsupported(
            c,
            "fmi2GetIntegerStatus",
            &format!("status kind {kind}: FMI 2.0 defines no integer status"),
        )
    }
}

/// `fmi2GetBooleanStatus`: `fmi2Terminated` is true once the plant stopped (the host
/// should end the simulation).
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`]; `value` points to one `fmi2Boolean`.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: *mut c_void,
    kind: c_int,
    value: *mut c_int,
) -> c_int {
    unsafe {
        with(c, "fmi2GetBooleanStatus", |i| {
            if kind == TERMINATED && !value.is_null() {
                *value = c_int::from(i.stopped());
                Ok(())
            } else {
                Err(FmuError::error(format!(
                    "status kind {kind}: fmi2GetBooleanStatus answers fmi2Terminated (3) only"
                )))
            }
        })
    }
}

/// `fmi2GetStringStatus`: `fmi2PendingStatus` only exists for asynchronous steps.
///
/// # Safety
/// `c` as for [`fmi2FreeInstance`].
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: *mut c_void,
    kind: c_int,
    _value: *mut *const c_char,
) -> c_int {
    let why = if kind == PENDING_STATUS {
        "no step is ever pending (canRunAsynchronuously = false)".to_string()
    } else {
        format!("status kind {kind}: no string status")
    };
    unsafe { unsupported(c, "fmi2GetStringStatus", &why) }
}
