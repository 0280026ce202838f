//! The FMI 2.0 co-simulation C API (`fmi2Functions.h`, `fmi2FunctionTypes.h`).
//!
//! FMI 2.0 has no arrays: element `i` (1-based) of the plant's array `a` is the scalar `a[i]`
//! with value reference [`fmi2_element_reference`]`(a, i - 1)`, at the fixed N of the FMU.
//! UInt64 variables are `Integer`s (every value fits 32 bits; `ticks_per_second` is set through
//! one, so at most 2^31 - 1 ticks per second here); the enumeration `boundary` is read
//! and written as an `Integer`.

#![allow(non_snake_case, clippy::missing_safety_doc)]

use std::borrow::Cow;
use std::ffi::{c_char, c_int, c_uint, c_void};

use crawler_physics::model_description::{
    fmi2_element_of, fmi2_element_reference, instantiation_token, vr,
};
use crawler_physics::slave::{LifecycleState, Slave, StepStatus};

use crate::instance::{
    c_string, category, cpu_refusal, free_instance, free_saved_state, guard, log_to, saved_state,
    slice, slice_mut, text, with_instance, Fmi2Logger, Instance, Logger, SavedState, Status,
};

/// `fmi2Component`.
pub type Fmi2Component = *mut c_void;
/// `fmi2FMUstate`.
pub type Fmi2FmuState = *mut c_void;
/// `fmi2ValueReference`.
pub type Fmi2ValueReference = c_uint;
/// `fmi2Status` (a C enum).
pub type Fmi2Status = c_int;
/// `fmi2Boolean` (an int: 0 false, anything else true).
pub type Fmi2Boolean = c_int;

/// `fmi2Type`: model exchange.
pub const FMI2_MODEL_EXCHANGE: c_int = 0;
/// `fmi2Type`: co-simulation.
pub const FMI2_CO_SIMULATION: c_int = 1;

/// `fmi2StatusKind`.
pub mod status_kind {
    /// `fmi2DoStepStatus`.
    pub const DO_STEP_STATUS: i32 = 0;
    /// `fmi2PendingStatus`.
    pub const PENDING_STATUS: i32 = 1;
    /// `fmi2LastSuccessfulTime`.
    pub const LAST_SUCCESSFUL_TIME: i32 = 2;
    /// `fmi2Terminated`.
    pub const TERMINATED: i32 = 3;
}

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct Fmi2CallbackFunctions {
    /// Logger (printf style).
    pub logger: Option<Fmi2Logger>,
    /// Memory allocation (not used: `canNotUseMemoryManagementFunctions = true`).
    pub allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    /// Memory release (not used).
    pub free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    /// Asynchronous step finished (not used: steps are synchronous).
    pub step_finished: Option<unsafe extern "C" fn(*mut c_void, Fmi2Status)>,
    /// Passed back to the logger.
    pub component_environment: *mut c_void,
}

fn code(s: Status) -> Fmi2Status {
    s as Fmi2Status
}

/// The number of cells N of this FMU (fixed: its arrays are scalars `u[1]`..`u[N]`).
fn fixed_cells() -> usize {
    crate::defaults::scenario().plant.numerics.cells
}

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: Fmi2Component,
    loggingOn: Fmi2Boolean,
    nCategories: usize,
    categories: *const *const c_char,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SetDebugLogging", false, |i| {
        let Some(cats) = slice(categories, nCategories) else {
            return i.error("fmi2SetDebugLogging: categories is NULL but nCategories > 0");
        };
        let mut names = Vec::new();
        for (k, &p) in cats.iter().enumerate() {
            match text(p, &format!("categories[{k}]"), true) {
                Ok(s) => names.push(s.to_string()),
                Err(e) => return i.error(&format!("fmi2SetDebugLogging: {e}")),
            }
        }
        i.set_debug_logging(loggingOn != 0, &names)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instanceName: *const c_char,
    fmuType: c_int,
    fmuGUID: *const c_char,
    _fmuResourceLocation: *const c_char,
    functions: *const Fmi2CallbackFunctions,
    _visible: Fmi2Boolean,
    loggingOn: Fmi2Boolean,
) -> Fmi2Component {
    guard(std::ptr::null_mut(), || {
        if functions.is_null() {
            return std::ptr::null_mut();
        }
        // SAFETY: non-NULL, and the importer passes a valid fmi2CallbackFunctions.
        let f = unsafe { &*functions };
        let logger = Logger::Fmi2(f.logger, f.component_environment);
        let fail = |name: &str, msg: &str| {
            log_to(
                logger,
                &c_string(name),
                Status::Error,
                category::ERROR,
                &format!("fmi2Instantiate: {msg}"),
            );
            std::ptr::null_mut()
        };
        let name = match text(instanceName, "instanceName", true) {
            Ok(n) => n,
            Err(e) => return fail("", &format!("{e}: give the instance a name")),
        };
        if fmuType != FMI2_CO_SIMULATION {
            return fail(
                name,
                &format!(
                    "fmuType = {fmuType}: this FMU supports co-simulation only (fmi2CoSimulation = 1)"
                ),
            );
        }
        let token = instantiation_token(fixed_cells());
        match text(fmuGUID, "fmuGUID", true) {
            Ok(g) if g == token => {}
            Ok(g) => {
                return fail(
                    name,
                    &format!(
                        "fmuGUID {g:?} is not this FMU's {token:?} (a modelDescription.xml of another build or N?)"
                    ),
                )
            }
            Err(e) => return fail(name, &e),
        }
        if let Some(why) = cpu_refusal() {
            return fail(name, &why);
        }
        match crate::defaults::slave(name) {
            Ok(slave) => {
                let inst = Instance::new(slave, name, logger, loggingOn != 0);
                inst.log(
                    Status::Ok,
                    category::EVENTS,
                    "instantiated (FMI 2.0 co-simulation)",
                );
                Box::into_raw(inst) as Fmi2Component
            }
            Err(e) => fail(name, &e.to_string()),
        }
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: Fmi2Component) {
    free_instance(c)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: Fmi2Component,
    _toleranceDefined: Fmi2Boolean,
    _tolerance: f64,
    startTime: f64,
    stopTimeDefined: Fmi2Boolean,
    stopTime: f64,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SetupExperiment", false, |i| {
        if i.slave.lifecycle() != LifecycleState::Instantiated {
            return i.error(&format!(
                "fmi2SetupExperiment is not allowed in state {:?} (only after fmi2Instantiate or fmi2Reset)",
                i.slave.lifecycle()
            ));
        }
        i.setup = (startTime, (stopTimeDefined != 0).then_some(stopTime));
        Status::Ok
    }))
}

fn report(i: &Instance, call: &str, r: Result<(), crawler_physics::slave::SlaveError>) -> Status {
    match r {
        Ok(()) => Status::Ok,
        Err(e) => i.error(&format!("{call}: {e}")),
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: Fmi2Component) -> Fmi2Status {
    code(with_instance(
        c,
        "fmi2EnterInitializationMode",
        false,
        |i| {
            let (start, stop) = i.setup;
            let r = i.slave.enter_initialization_mode(start, stop);
            report(i, "fmi2EnterInitializationMode", r)
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: Fmi2Component) -> Fmi2Status {
    code(with_instance(c, "fmi2ExitInitializationMode", false, |i| {
        let r = i.slave.exit_initialization_mode();
        report(i, "fmi2ExitInitializationMode", r)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: Fmi2Component) -> Fmi2Status {
    code(with_instance(c, "fmi2Terminate", false, |i| {
        let r = i.slave.terminate();
        report(i, "fmi2Terminate", r)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: Fmi2Component) -> Fmi2Status {
    code(with_instance(c, "fmi2Reset", true, |i| {
        let r = i.slave.reset();
        i.setup = (0.0, None);
        i.poisoned = false;
        report(i, "fmi2Reset", r)
    }))
}

/// Reads Reals: scalars directly, array elements from each array fetched once per call.
fn get_real(i: &Instance, vrs: &[u32], out: &mut [f64]) -> Status {
    let mut arrays: Vec<(u32, Cow<'_, [f64]>)> = Vec::new();
    for (k, &r) in vrs.iter().enumerate() {
        let value = match fmi2_element_of(r) {
            Some((a, e)) => {
                let pos = match arrays.iter().position(|(b, _)| *b == a) {
                    Some(p) => Some(p),
                    None => i.slave.float64_array(a).map(|v| {
                        arrays.push((a, v));
                        arrays.len() - 1
                    }),
                };
                pos.and_then(|p| arrays[p].1.get(e).copied())
            }
            None => i.slave.float64_scalar(r),
        };
        match value {
            Some(x) => out[k] = x,
            None => {
                return i.error(&format!(
                    "fmi2GetReal: no Real variable has value reference {r}"
                ))
            }
        }
    }
    Status::Ok
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *mut f64,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetReal", false, |i| {
        match (slice(vrs, nvr), slice_mut(values, nvr)) {
            (Some(r), Some(v)) => get_real(i, r, v),
            _ => i.error("fmi2GetReal: vr or value is NULL but nvr > 0"),
        }
    }))
}

fn integer_of(i: &Instance, r: u32) -> Option<i64> {
    if r == vr::BOUNDARY {
        return i.slave.get_int64(&[r]).ok().map(|v| v[0]);
    }
    i.slave.get_uint64(&[r]).ok().map(|v| v[0] as i64)
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *mut c_int,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetInteger", false, |i| {
        let (Some(r), Some(v)) = (slice(vrs, nvr), slice_mut(values, nvr)) else {
            return i.error("fmi2GetInteger: vr or value is NULL but nvr > 0");
        };
        for (k, &x) in r.iter().enumerate() {
            match integer_of(i, x).and_then(|n| c_int::try_from(n).ok()) {
                Some(n) => v[k] = n,
                None => {
                    return i.error(&format!(
                        "fmi2GetInteger: no Integer variable has value reference {x}"
                    ))
                }
            }
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *mut Fmi2Boolean,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetBoolean", false, |i| {
        let (Some(r), Some(v)) = (slice(vrs, nvr), slice_mut(values, nvr)) else {
            return i.error("fmi2GetBoolean: vr or value is NULL but nvr > 0");
        };
        let stuck = i.slave.plant().stuck();
        for (k, &x) in r.iter().enumerate() {
            match fmi2_element_of(x) {
                Some((vr::STUCK, e)) if e < stuck.len() => v[k] = stuck[e] as Fmi2Boolean,
                _ => {
                    return i.error(&format!(
                        "fmi2GetBoolean: no Boolean variable has value reference {x}"
                    ))
                }
            }
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *mut *const c_char,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetString", false, |i| {
        let (Some(r), Some(v)) = (slice(vrs, nvr), slice_mut(values, nvr)) else {
            return i.error("fmi2GetString: vr or value is NULL but nvr > 0");
        };
        match i.slave.get_string(r) {
            Ok(texts) => {
                i.strings = texts.iter().map(|t| c_string(t)).collect();
                for (k, s) in i.strings.iter().enumerate() {
                    v[k] = s.as_ptr();
                }
                Status::Ok
            }
            Err(e) => i.error(&format!("fmi2GetString: {e}")),
        }
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *const f64,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SetReal", false, |i| {
        let (Some(r), Some(v)) = (slice(vrs, nvr), slice(values, nvr)) else {
            return i.error("fmi2SetReal: vr or value is NULL but nvr > 0");
        };
        let mut scalars = (Vec::new(), Vec::new());
        let mut field: Option<Vec<f64>> = None;
        for (&x, &value) in r.iter().zip(v) {
            match fmi2_element_of(x) {
                None => {
                    scalars.0.push(x);
                    scalars.1.push(value);
                }
                Some((vr::MUSCLE_FORCE, e)) if e < i.slave.params().numerics.cells => {
                    let f = field.get_or_insert_with(|| {
                        i.slave
                            .float64_array(vr::MUSCLE_FORCE)
                            .map(|a| a.into_owned())
                            .unwrap_or_default()
                    });
                    f[e] = value;
                }
                Some(_) => {
                    return i.error(&format!(
                        "fmi2SetReal: no settable Real variable has value reference {x}"
                    ))
                }
            }
        }
        if !scalars.0.is_empty() {
            let res = i.slave.set_float64(&scalars.0, &scalars.1);
            if let Err(e) = res {
                return i.error(&format!("fmi2SetReal: {e}"));
            }
        }
        if let Some(f) = field {
            let res = i.slave.set_float64(&[vr::MUSCLE_FORCE], &f);
            if let Err(e) = res {
                return i.error(&format!("fmi2SetReal: {e}"));
            }
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *const c_int,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SetInteger", false, |i| {
        let (Some(r), Some(v)) = (slice(vrs, nvr), slice(values, nvr)) else {
            return i.error("fmi2SetInteger: vr or value is NULL but nvr > 0");
        };
        for (&x, &value) in r.iter().zip(v) {
            let res = match x {
                vr::CELLS => {
                    let n = i.slave.params().numerics.cells;
                    if i64::from(value) == n as i64 {
                        Ok(())
                    } else {
                        return i.error(&format!(
                            "fmi2SetInteger: invalid cells = {value}: allowed {n} only (an FMI 2.0 FMU has a fixed N: \
                             its arrays are the scalars u[1]..u[{n}]; the FMI 3.0 FMU sets cells in Configuration Mode)"
                        ));
                    }
                }
                vr::BOUNDARY => i.slave.set_int64(&[x], &[i64::from(value)]),
                vr::ACTUATION_MODE => match u64::try_from(value) {
                    Ok(m) => i.slave.set_uint64(&[x], &[m]),
                    Err(_) => {
                        return i.error(&format!(
                            "fmi2SetInteger: invalid actuation_mode = {value}: allowed 0 (none), 1 (wave) or 2 (field)"
                        ))
                    }
                },
                vr::TICKS_PER_SECOND => match u64::try_from(value) {
                    Ok(t) => i.slave.set_uint64(&[x], &[t]),
                    Err(_) => {
                        return i.error(&format!(
                            "fmi2SetInteger: invalid ticks_per_second = {value}: allowed 0 (the plant's own clock) \
                             or a clock of 1 to {} ticks per second (1000000000 for nanoseconds)",
                            c_int::MAX
                        ))
                    }
                },
                // anything else is refused by the slave, which names it
                _ => i.slave.set_uint64(&[x], &[value.max(0) as u64]),
            };
            if let Err(e) = res {
                return i.error(&format!("fmi2SetInteger: {e}"));
            }
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *const Fmi2Boolean,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SetBoolean", false, |i| {
        match (slice(vrs, nvr), slice(values, nvr)) {
            (Some([]), _) => Status::Ok,
            (Some(r), Some(_)) => i.error(&format!(
                "fmi2SetBoolean: value reference {} is not settable (the only Booleans, stuck[i], are outputs)",
                r[0]
            )),
            _ => i.error("fmi2SetBoolean: vr or value is NULL but nvr > 0"),
        }
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: Fmi2Component,
    vrs: *const Fmi2ValueReference,
    nvr: usize,
    values: *const *const c_char,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SetString", false, |i| {
        let (Some(r), Some(v)) = (slice(vrs, nvr), slice(values, nvr)) else {
            return i.error("fmi2SetString: vr or value is NULL but nvr > 0");
        };
        let mut texts = Vec::with_capacity(v.len());
        for (k, &p) in v.iter().enumerate() {
            match text(p, &format!("value[{k}]"), false) {
                Ok(s) => texts.push(s),
                Err(e) => return i.error(&format!("fmi2SetString: {e}")),
            }
        }
        let res = i.slave.set_string(r, &texts);
        report(i, "fmi2SetString", res)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: Fmi2Component, state: *mut Fmi2FmuState) -> Fmi2Status {
    code(with_instance(c, "fmi2GetFMUstate", false, |i| {
        if state.is_null() {
            return i.error("fmi2GetFMUstate: FMUstate is NULL");
        }
        let plant_state = i.slave.get_state();
        // SAFETY: non-NULL; the importer passes a pointer to its handle variable.
        let slot = unsafe { &mut *state };
        // SAFETY: a non-NULL handle must be one of ours, to be overwritten.
        match unsafe { saved_state(*slot) } {
            Some(existing) => {
                existing.state = plant_state;
                existing.bytes = None;
            }
            None if slot.is_null() => {
                *slot = Box::into_raw(SavedState::new(plant_state)) as Fmi2FmuState
            }
            None => {
                return i
                    .error("fmi2GetFMUstate: *FMUstate is neither NULL nor a state of this FMU")
            }
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: Fmi2Component, state: Fmi2FmuState) -> Fmi2Status {
    code(with_instance(c, "fmi2SetFMUstate", false, |i| {
        // SAFETY: the handle is checked by its tag.
        let Some(s) = (unsafe { saved_state(state) }) else {
            return i.error("fmi2SetFMUstate: FMUstate is NULL or not a state of this FMU");
        };
        let res = i.slave.set_state(&s.state);
        report(i, "fmi2SetFMUstate", res)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(
    c: Fmi2Component,
    state: *mut Fmi2FmuState,
) -> Fmi2Status {
    code(with_instance(c, "fmi2FreeFMUstate", true, |i| {
        if state.is_null() {
            return i.error("fmi2FreeFMUstate: FMUstate is NULL");
        }
        // SAFETY: non-NULL pointer to the importer's handle; the handle is checked by its tag.
        unsafe {
            free_saved_state(*state);
            *state = std::ptr::null_mut();
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: Fmi2Component,
    state: Fmi2FmuState,
    size: *mut usize,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SerializedFMUstateSize", false, |i| {
        // SAFETY: the handle is checked by its tag.
        let (Some(s), false) = (unsafe { saved_state(state) }, size.is_null()) else {
            return i.error("fmi2SerializedFMUstateSize: FMUstate or size is NULL or invalid");
        };
        // SAFETY: non-NULL.
        unsafe { *size = s.bytes().len() };
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: Fmi2Component,
    state: Fmi2FmuState,
    bytes: *mut c_char,
    size: usize,
) -> Fmi2Status {
    code(with_instance(c, "fmi2SerializeFMUstate", false, |i| {
        // SAFETY: the handle is checked by its tag.
        let Some(s) = (unsafe { saved_state(state) }) else {
            return i.error("fmi2SerializeFMUstate: FMUstate is NULL or not a state of this FMU");
        };
        let data = s.bytes();
        if size != data.len() {
            return i.error(&format!(
                "fmi2SerializeFMUstate: size = {size}, but the state takes {} bytes (fmi2SerializedFMUstateSize)",
                data.len()
            ));
        }
        let Some(out) = slice_mut(bytes as *mut u8, size) else {
            return i.error("fmi2SerializeFMUstate: serializedState is NULL");
        };
        out.copy_from_slice(data);
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: Fmi2Component,
    bytes: *const c_char,
    size: usize,
    state: *mut Fmi2FmuState,
) -> Fmi2Status {
    code(with_instance(c, "fmi2DeSerializeFMUstate", false, |i| {
        let (Some(data), false) = (slice(bytes as *const u8, size), state.is_null()) else {
            return i.error("fmi2DeSerializeFMUstate: serializedState or FMUstate is NULL");
        };
        match Slave::deserialize_state(data) {
            Ok(s) => {
                // SAFETY: non-NULL pointer to the importer's handle variable, which receives a
                // new state (its old content is not read: it may be uninitialised).
                unsafe { *state = Box::into_raw(SavedState::new(s)) as Fmi2FmuState };
                Status::Ok
            }
            Err(e) => i.error(&format!("fmi2DeSerializeFMUstate: {e}")),
        }
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: Fmi2Component,
    _vUnknown: *const Fmi2ValueReference,
    _nUnknown: usize,
    _vKnown: *const Fmi2ValueReference,
    _nKnown: usize,
    _dvKnown: *const f64,
    _dvUnknown: *mut f64,
) -> Fmi2Status {
    code(with_instance(
        c,
        "fmi2GetDirectionalDerivative",
        false,
        |i| {
            i.error("fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative = false)")
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: Fmi2Component,
    _vr: *const Fmi2ValueReference,
    _nvr: usize,
    _order: *const c_int,
    _value: *const f64,
) -> Fmi2Status {
    code(with_instance(
        c,
        "fmi2SetRealInputDerivatives",
        false,
        |i| {
            i.error("fmi2SetRealInputDerivatives: inputs are held over each step (canInterpolateInputs = false)")
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: Fmi2Component,
    _vr: *const Fmi2ValueReference,
    _nvr: usize,
    _order: *const c_int,
    _value: *mut f64,
) -> Fmi2Status {
    code(with_instance(
        c,
        "fmi2GetRealOutputDerivatives",
        false,
        |i| i.error("fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder = 0)"),
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: Fmi2Component,
    currentCommunicationPoint: f64,
    communicationStepSize: f64,
    _noSetFMUStatePriorToCurrentPoint: Fmi2Boolean,
) -> Fmi2Status {
    code(with_instance(c, "fmi2DoStep", false, |i| {
        let status = match i
            .slave
            .do_step(currentCommunicationPoint, communicationStepSize)
        {
            StepStatus::Ok => Status::Ok,
            StepStatus::Discard {
                last_successful_time,
                reason,
            } => {
                i.log(
                    Status::Discard,
                    category::DISCARD,
                    &format!("fmi2DoStep: step discarded, the FMU stays at t = {last_successful_time} s: {reason}"),
                );
                Status::Discard
            }
            StepStatus::Error(e) => i.error(&format!("fmi2DoStep: {e}")),
        };
        i.last_step = status;
        status
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: Fmi2Component) -> Fmi2Status {
    code(with_instance(c, "fmi2CancelStep", false, |i| {
        i.error("fmi2CancelStep: steps are synchronous (fmi2DoStep never returns fmi2Pending)")
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(
    c: Fmi2Component,
    kind: c_int,
    value: *mut Fmi2Status,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetStatus", false, |i| {
        if value.is_null() {
            return i.error("fmi2GetStatus: value is NULL");
        }
        if kind != status_kind::DO_STEP_STATUS {
            return i.error(&format!(
                "fmi2GetStatus: status kind {kind} has no fmi2Status value (fmi2DoStepStatus = 0 has)"
            ));
        }
        // SAFETY: non-NULL.
        unsafe { *value = i.last_step as Fmi2Status };
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(
    c: Fmi2Component,
    kind: c_int,
    value: *mut f64,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetRealStatus", false, |i| {
        if value.is_null() {
            return i.error("fmi2GetRealStatus: value is NULL");
        }
        if kind != status_kind::LAST_SUCCESSFUL_TIME {
            return i.error(&format!(
                "fmi2GetRealStatus: status kind {kind} has no Real value (fmi2LastSuccessfulTime = 2 has)"
            ));
        }
        // SAFETY: non-NULL.
        unsafe { *value = i.slave.plant().time() };
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(
    c: Fmi2Component,
    kind: c_int,
    _value: *mut c_int,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetIntegerStatus", false, |i| {
        i.error(&format!(
            "fmi2GetIntegerStatus: status kind {kind} has no Integer value"
        ))
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(
    c: Fmi2Component,
    kind: c_int,
    value: *mut Fmi2Boolean,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetBooleanStatus", false, |i| {
        if value.is_null() {
            return i.error("fmi2GetBooleanStatus: value is NULL");
        }
        if kind != status_kind::TERMINATED {
            return i.error(&format!(
                "fmi2GetBooleanStatus: status kind {kind} has no Boolean value (fmi2Terminated = 3 has)"
            ));
        }
        // The plant never asks to end the simulation.
        // SAFETY: non-NULL.
        unsafe { *value = 0 };
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: Fmi2Component,
    kind: c_int,
    _value: *mut *const c_char,
) -> Fmi2Status {
    code(with_instance(c, "fmi2GetStringStatus", false, |i| {
        i.error(&format!(
            "fmi2GetStringStatus: status kind {kind} has no String value (fmi2DoStep never returns fmi2Pending)"
        ))
    }))
}

/// The FMI 2.0 value reference of `name[index]` (1-based), for programs that drive the FMU.
pub fn element_reference(array: u32, index: usize) -> u32 {
    fmi2_element_reference(array, index - 1)
}
