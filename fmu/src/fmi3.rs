//! The FMI 3.0 co-simulation C API (`fmi3Functions.h`, `fmi3FunctionTypes.h`).
//!
//! Arrays are real arrays (`u` is one value reference with `cells` values); `cells` and
//! `boundary` are structural parameters, set in Configuration Mode (or right after
//! instantiation). `fmi3Boolean` arguments are read as bytes (any non-zero byte is true), so a
//! foreign value is never undefined behaviour here.

#![allow(non_snake_case, clippy::missing_safety_doc, clippy::too_many_arguments)]

use std::ffi::{c_char, c_int, c_void};

use crawler_physics::model_description::{instantiation_token, is_array, variable_name, VarType};
use crawler_physics::slave::{LifecycleState, Slave, StepStatus};

use crate::instance::{
    c_string, category, cpu_refusal, free_instance, free_saved_state, guard, log_to, saved_state,
    slice, slice_mut, text, with_instance, Fmi3Logger, Instance, Logger, SavedState, Status,
};

/// `fmi3Instance`.
pub type Fmi3Instance = *mut c_void;
/// `fmi3FMUState`.
pub type Fmi3FmuState = *mut c_void;
/// `fmi3ValueReference`.
pub type Fmi3ValueReference = u32;
/// `fmi3Status` (a C enum).
pub type Fmi3Status = c_int;
/// `fmi3Boolean` (C `bool`), read as a byte.
pub type Fmi3Boolean = u8;

fn code(s: Status) -> Fmi3Status {
    s as Fmi3Status
}

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: Fmi3Instance,
    loggingOn: Fmi3Boolean,
    nCategories: usize,
    categories: *const *const c_char,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetDebugLogging", false, |i| {
        let Some(cats) = slice(categories, nCategories) else {
            return i.error("fmi3SetDebugLogging: categories is NULL but nCategories > 0");
        };
        let mut names = Vec::new();
        for (k, &p) in cats.iter().enumerate() {
            match text(p, &format!("categories[{k}]"), true) {
                Ok(s) => names.push(s.to_string()),
                Err(e) => return i.error(&format!("fmi3SetDebugLogging: {e}")),
            }
        }
        i.set_debug_logging(loggingOn != 0, &names)
    }))
}

fn refuse_interface(
    instanceName: *const c_char,
    logMessage: Option<Fmi3Logger>,
    env: *mut c_void,
    call: &str,
) -> Fmi3Instance {
    guard(std::ptr::null_mut(), || {
        // SAFETY: NULL or a C string per the FMI contract.
        let name = unsafe { text(instanceName, "instanceName", false) }.unwrap_or("");
        log_to(
            Logger::Fmi3(logMessage, env),
            &c_string(name),
            Status::Error,
            category::ERROR,
            &format!("{call}: this FMU supports co-simulation only (fmi3InstantiateCoSimulation)"),
        );
        std::ptr::null_mut()
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(
    instanceName: *const c_char,
    _instantiationToken: *const c_char,
    _resourcePath: *const c_char,
    _visible: Fmi3Boolean,
    _loggingOn: Fmi3Boolean,
    instanceEnvironment: *mut c_void,
    logMessage: Option<Fmi3Logger>,
) -> Fmi3Instance {
    refuse_interface(
        instanceName,
        logMessage,
        instanceEnvironment,
        "fmi3InstantiateModelExchange",
    )
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
    instanceName: *const c_char,
    _instantiationToken: *const c_char,
    _resourcePath: *const c_char,
    _visible: Fmi3Boolean,
    _loggingOn: Fmi3Boolean,
    instanceEnvironment: *mut c_void,
    logMessage: Option<Fmi3Logger>,
    _clockUpdate: *const c_void,
    _lockPreemption: *const c_void,
    _unlockPreemption: *const c_void,
) -> Fmi3Instance {
    refuse_interface(
        instanceName,
        logMessage,
        instanceEnvironment,
        "fmi3InstantiateScheduledExecution",
    )
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: *const c_char,
    instantiationToken: *const c_char,
    _resourcePath: *const c_char,
    _visible: Fmi3Boolean,
    loggingOn: Fmi3Boolean,
    eventModeUsed: Fmi3Boolean,
    _earlyReturnAllowed: Fmi3Boolean,
    requiredIntermediateVariables: *const Fmi3ValueReference,
    nRequiredIntermediateVariables: usize,
    instanceEnvironment: *mut c_void,
    logMessage: Option<Fmi3Logger>,
    _intermediateUpdate: *const c_void,
) -> Fmi3Instance {
    guard(std::ptr::null_mut(), || {
        let logger = Logger::Fmi3(logMessage, instanceEnvironment);
        let fail = |name: &str, msg: &str| {
            log_to(
                logger,
                &c_string(name),
                Status::Error,
                category::ERROR,
                &format!("fmi3InstantiateCoSimulation: {msg}"),
            );
            std::ptr::null_mut()
        };
        let name = match text(instanceName, "instanceName", true) {
            Ok(n) => n,
            Err(e) => return fail("", &format!("{e}: give the instance a name")),
        };
        let token = instantiation_token(crate::defaults::scenario().plant.numerics.cells);
        match text(instantiationToken, "instantiationToken", true) {
            Ok(g) if g == token => {}
            Ok(g) => {
                return fail(
                    name,
                    &format!(
                        "instantiationToken {g:?} is not this FMU's {token:?} (a modelDescription.xml of another build?)"
                    ),
                )
            }
            Err(e) => return fail(name, &e),
        }
        if eventModeUsed != 0 {
            return fail(
                name,
                "eventModeUsed = true, but this FMU has no event mode (hasEventMode = false)",
            );
        }
        if slice(
            requiredIntermediateVariables,
            nRequiredIntermediateVariables,
        )
        .is_none()
        {
            return fail(
                name,
                "requiredIntermediateVariables is NULL but nRequiredIntermediateVariables > 0",
            );
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
                    "instantiated (FMI 3.0 co-simulation)",
                );
                Box::into_raw(inst) as Fmi3Instance
            }
            Err(e) => fail(name, &e.to_string()),
        }
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: Fmi3Instance) {
    free_instance(instance)
}

fn report(i: &Instance, call: &str, r: Result<(), crawler_physics::slave::SlaveError>) -> Status {
    match r {
        Ok(()) => Status::Ok,
        Err(e) => i.error(&format!("{call}: {e}")),
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterInitializationMode(
    instance: Fmi3Instance,
    _toleranceDefined: Fmi3Boolean,
    _tolerance: f64,
    startTime: f64,
    stopTimeDefined: Fmi3Boolean,
    stopTime: f64,
) -> Fmi3Status {
    code(with_instance(
        instance,
        "fmi3EnterInitializationMode",
        false,
        |i| {
            let r = i
                .slave
                .enter_initialization_mode(startTime, (stopTimeDefined != 0).then_some(stopTime));
            report(i, "fmi3EnterInitializationMode", r)
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ExitInitializationMode(instance: Fmi3Instance) -> Fmi3Status {
    code(with_instance(
        instance,
        "fmi3ExitInitializationMode",
        false,
        |i| {
            let r = i.slave.exit_initialization_mode();
            report(i, "fmi3ExitInitializationMode", r)
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterEventMode(instance: Fmi3Instance) -> Fmi3Status {
    code(with_instance(instance, "fmi3EnterEventMode", false, |i| {
        i.error("fmi3EnterEventMode: this FMU has no event mode (hasEventMode = false)")
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterStepMode(instance: Fmi3Instance) -> Fmi3Status {
    code(with_instance(instance, "fmi3EnterStepMode", false, |i| {
        i.error("fmi3EnterStepMode: only used with event mode, which this FMU does not have; fmi3ExitInitializationMode enters step mode")
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Terminate(instance: Fmi3Instance) -> Fmi3Status {
    code(with_instance(instance, "fmi3Terminate", false, |i| {
        let r = i.slave.terminate();
        report(i, "fmi3Terminate", r)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3Reset(instance: Fmi3Instance) -> Fmi3Status {
    code(with_instance(instance, "fmi3Reset", true, |i| {
        let r = i.slave.reset();
        i.poisoned = false;
        report(i, "fmi3Reset", r)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3EnterConfigurationMode(instance: Fmi3Instance) -> Fmi3Status {
    code(with_instance(
        instance,
        "fmi3EnterConfigurationMode",
        false,
        |i| {
            let r = i.slave.enter_configuration_mode();
            report(i, "fmi3EnterConfigurationMode", r)
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3ExitConfigurationMode(instance: Fmi3Instance) -> Fmi3Status {
    code(with_instance(
        instance,
        "fmi3ExitConfigurationMode",
        false,
        |i| {
            let r = i.slave.exit_configuration_mode();
            report(i, "fmi3ExitConfigurationMode", r)
        },
    ))
}

/// Number of values the value references `vrs` of type `ty` take (arrays: `cells`), or the
/// first reference that is not of that type.
fn count_values(i: &Instance, vrs: &[u32], ty: VarType) -> Result<usize, u32> {
    let n = i.slave.params().numerics.cells;
    vrs.iter()
        .try_fold(0usize, |acc, &r| match variable_name(r) {
            Some((_, t)) if t == ty => Ok(acc + if is_array(r) { n } else { 1 }),
            _ => Err(r),
        })
}

/// Checks the arguments of a getter or setter: the references are of type `ty` and take exactly
/// `nValues` values. Returns the references, or the status already logged.
fn checked<'a>(
    i: &Instance,
    call: &str,
    ty: VarType,
    vrs: *const Fmi3ValueReference,
    nvr: usize,
    nValues: usize,
    values_null: bool,
) -> Result<&'a [u32], Status> {
    // SAFETY: the importer passes nvr value references (checked for NULL).
    let Some(r) = (unsafe { slice(vrs, nvr) }) else {
        return Err(i.error(&format!(
            "{call}: valueReferences is NULL but nValueReferences = {nvr}"
        )));
    };
    let expected = match count_values(i, r, ty) {
        Ok(n) => n,
        Err(bad) => {
            return Err(i.error(&format!(
                "{call}: no {ty:?} variable has value reference {bad}"
            )))
        }
    };
    if nValues != expected {
        return Err(i.error(&format!(
            "{call}: nValues = {nValues}, but the value references take {expected} values \
             (each array takes cells = {} values)",
            i.slave.params().numerics.cells
        )));
    }
    if values_null && nValues > 0 {
        return Err(i.error(&format!("{call}: values is NULL but nValues = {nValues}")));
    }
    Ok(r)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *mut f64,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3GetFloat64", false, |i| {
        let r = match checked(
            i,
            "fmi3GetFloat64",
            VarType::Float64,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        let out = slice_mut(values, nValues).expect("checked");
        let mut k = 0;
        for &x in r {
            if let Some(a) = i.slave.float64_array(x) {
                out[k..k + a.len()].copy_from_slice(&a);
                k += a.len();
            } else if let Some(v) = i.slave.float64_scalar(x) {
                out[k] = v;
                k += 1;
            } else {
                return i.error(&format!(
                    "fmi3GetFloat64: value reference {x} cannot be read"
                ));
            }
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt64(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *mut u64,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3GetUInt64", false, |i| {
        let r = match checked(
            i,
            "fmi3GetUInt64",
            VarType::UInt64,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        match i.slave.get_uint64(r) {
            Ok(v) => {
                slice_mut(values, nValues)
                    .expect("checked")
                    .copy_from_slice(&v);
                Status::Ok
            }
            Err(e) => i.error(&format!("fmi3GetUInt64: {e}")),
        }
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt64(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *mut i64,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3GetInt64", false, |i| {
        let r = match checked(
            i,
            "fmi3GetInt64",
            VarType::Enumeration,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        match i.slave.get_int64(r) {
            Ok(v) => {
                slice_mut(values, nValues)
                    .expect("checked")
                    .copy_from_slice(&v);
                Status::Ok
            }
            Err(e) => i.error(&format!("fmi3GetInt64: {e}")),
        }
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetBoolean(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *mut Fmi3Boolean,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3GetBoolean", false, |i| {
        let r = match checked(
            i,
            "fmi3GetBoolean",
            VarType::Boolean,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        match i.slave.get_boolean(r) {
            Ok(v) => {
                let out = slice_mut(values, nValues).expect("checked");
                for (o, b) in out.iter_mut().zip(v) {
                    *o = b as u8;
                }
                Status::Ok
            }
            Err(e) => i.error(&format!("fmi3GetBoolean: {e}")),
        }
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetString(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *mut *const c_char,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3GetString", false, |i| {
        let r = match checked(
            i,
            "fmi3GetString",
            VarType::String,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        match i.slave.get_string(r) {
            Ok(texts) => {
                i.strings = texts.iter().map(|t| c_string(t)).collect();
                let out = slice_mut(values, nValues).expect("checked");
                for (o, s) in out.iter_mut().zip(&i.strings) {
                    *o = s.as_ptr();
                }
                Status::Ok
            }
            Err(e) => i.error(&format!("fmi3GetString: {e}")),
        }
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *const f64,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetFloat64", false, |i| {
        let r = match checked(
            i,
            "fmi3SetFloat64",
            VarType::Float64,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        let v = slice(values, nValues).expect("checked");
        let res = i.slave.set_float64(r, v);
        report(i, "fmi3SetFloat64", res)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt64(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *const u64,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetUInt64", false, |i| {
        let r = match checked(
            i,
            "fmi3SetUInt64",
            VarType::UInt64,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        let v = slice(values, nValues).expect("checked");
        let res = i.slave.set_uint64(r, v);
        report(i, "fmi3SetUInt64", res)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt64(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *const i64,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetInt64", false, |i| {
        let r = match checked(
            i,
            "fmi3SetInt64",
            VarType::Enumeration,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        let v = slice(values, nValues).expect("checked");
        let res = i.slave.set_int64(r, v);
        report(i, "fmi3SetInt64", res)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetBoolean(
    instance: Fmi3Instance,
    _valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    _values: *const Fmi3Boolean,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetBoolean", false, |i| {
        if nValueReferences == 0 && nValues == 0 {
            return Status::Ok;
        }
        i.error(
            "fmi3SetBoolean: no Boolean variable is settable (the only one, stuck, is an output)",
        )
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetString(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    values: *const *const c_char,
    nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetString", false, |i| {
        let r = match checked(
            i,
            "fmi3SetString",
            VarType::String,
            valueReferences,
            nValueReferences,
            nValues,
            values.is_null(),
        ) {
            Ok(r) => r,
            Err(s) => return s,
        };
        let v = slice(values, nValues).expect("checked");
        let mut texts = Vec::with_capacity(v.len());
        for (k, &p) in v.iter().enumerate() {
            match text(p, &format!("values[{k}]"), false) {
                Ok(s) => texts.push(s),
                Err(e) => return i.error(&format!("fmi3SetString: {e}")),
            }
        }
        let res = i.slave.set_string(r, &texts);
        report(i, "fmi3SetString", res)
    }))
}

/// Getters and setters of types this FMU has no variables of: OK for zero references, an
/// Error naming the first reference otherwise.
macro_rules! no_variables_of_type {
    ($($name:ident: $t:ty;)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            instance: Fmi3Instance,
            valueReferences: *const Fmi3ValueReference,
            nValueReferences: usize,
            _values: $t,
            _nValues: usize,
        ) -> Fmi3Status {
            code(with_instance(instance, stringify!($name), false, |i| {
                match slice(valueReferences, nValueReferences) {
                    Some([]) => Status::Ok,
                    Some(r) => i.error(&format!(
                        "{}: no variable of this type has value reference {} (the FMU has Float64, UInt64, Int64 (enumeration), Boolean and String variables)",
                        stringify!($name),
                        r[0]
                    )),
                    None => i.error(&format!("{}: valueReferences is NULL", stringify!($name))),
                }
            }))
        }
    )*};
}

no_variables_of_type! {
    fmi3GetFloat32: *mut f32;
    fmi3GetInt8: *mut i8;
    fmi3GetUInt8: *mut u8;
    fmi3GetInt16: *mut i16;
    fmi3GetUInt16: *mut u16;
    fmi3GetInt32: *mut i32;
    fmi3GetUInt32: *mut u32;
    fmi3SetFloat32: *const f32;
    fmi3SetInt8: *const i8;
    fmi3SetUInt8: *const u8;
    fmi3SetInt16: *const i16;
    fmi3SetUInt16: *const u16;
    fmi3SetInt32: *const i32;
    fmi3SetUInt32: *const u32;
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetBinary(
    instance: Fmi3Instance,
    valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *mut usize,
    _values: *mut *const u8,
    _nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3GetBinary", false, |i| {
        let _ = valueReferences;
        if nValueReferences == 0 {
            return Status::Ok;
        }
        i.error("fmi3GetBinary: the FMU has no Binary variables")
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetBinary(
    instance: Fmi3Instance,
    _valueReferences: *const Fmi3ValueReference,
    nValueReferences: usize,
    _valueSizes: *const usize,
    _values: *const *const u8,
    _nValues: usize,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetBinary", false, |i| {
        if nValueReferences == 0 {
            return Status::Ok;
        }
        i.error("fmi3SetBinary: the FMU has no Binary variables")
    }))
}

/// Functions of features this FMU does not have (clocks, events, model exchange, derivatives):
/// each logs why and returns Error.
macro_rules! not_provided {
    ($($name:ident($($arg:ident: $t:ty),*) => $why:expr;)*) => {$(
        #[no_mangle]
        pub unsafe extern "C" fn $name(instance: Fmi3Instance $(, $arg: $t)*) -> Fmi3Status {
            $(let _ = $arg;)*
            code(with_instance(instance, stringify!($name), false, |i| {
                i.error(&format!("{}: {}", stringify!($name), $why))
            }))
        }
    )*};
}

not_provided! {
    fmi3GetClock(vrs: *const u32, n: usize, values: *mut u8) => "the FMU has no clocks";
    fmi3SetClock(vrs: *const u32, n: usize, values: *const u8) => "the FMU has no clocks";
    fmi3GetIntervalDecimal(vrs: *const u32, n: usize, intervals: *mut f64, qualifiers: *mut c_int) => "the FMU has no clocks";
    fmi3GetIntervalFraction(vrs: *const u32, n: usize, counters: *mut u64, resolutions: *mut u64, qualifiers: *mut c_int) => "the FMU has no clocks";
    fmi3GetShiftDecimal(vrs: *const u32, n: usize, shifts: *mut f64) => "the FMU has no clocks";
    fmi3GetShiftFraction(vrs: *const u32, n: usize, counters: *mut u64, resolutions: *mut u64) => "the FMU has no clocks";
    fmi3SetIntervalDecimal(vrs: *const u32, n: usize, intervals: *const f64) => "the FMU has no clocks";
    fmi3SetIntervalFraction(vrs: *const u32, n: usize, counters: *const u64, resolutions: *const u64) => "the FMU has no clocks";
    fmi3SetShiftDecimal(vrs: *const u32, n: usize, shifts: *const f64) => "the FMU has no clocks";
    fmi3SetShiftFraction(vrs: *const u32, n: usize, counters: *const u64, resolutions: *const u64) => "the FMU has no clocks";
    fmi3EvaluateDiscreteStates() => "the FMU has no event mode";
    fmi3UpdateDiscreteStates(a: *mut u8, b: *mut u8, c: *mut u8, d: *mut u8, e: *mut u8, t: *mut f64) => "the FMU has no event mode";
    fmi3EnterContinuousTimeMode() => "the FMU supports co-simulation only";
    fmi3CompletedIntegratorStep(no_set: Fmi3Boolean, enter: *mut u8, term: *mut u8) => "the FMU supports co-simulation only";
    fmi3SetTime(time: f64) => "the FMU supports co-simulation only";
    fmi3SetContinuousStates(x: *const f64, n: usize) => "the FMU supports co-simulation only";
    fmi3GetContinuousStateDerivatives(dx: *mut f64, n: usize) => "the FMU supports co-simulation only";
    fmi3GetEventIndicators(z: *mut f64, n: usize) => "the FMU supports co-simulation only";
    fmi3GetContinuousStates(x: *mut f64, n: usize) => "the FMU supports co-simulation only";
    fmi3GetNominalsOfContinuousStates(x: *mut f64, n: usize) => "the FMU supports co-simulation only";
    fmi3GetNumberOfEventIndicators(n: *mut usize) => "the FMU supports co-simulation only";
    fmi3GetNumberOfContinuousStates(n: *mut usize) => "the FMU supports co-simulation only";
    fmi3GetOutputDerivatives(vrs: *const u32, n: usize, orders: *const i32, values: *mut f64, nv: usize) => "not provided (maxOutputDerivativeOrder = 0)";
    fmi3GetDirectionalDerivative(u: *const u32, nu: usize, k: *const u32, nk: usize, seed: *const f64, ns: usize, sens: *mut f64, nsens: usize) => "not provided (providesDirectionalDerivatives = false)";
    fmi3GetAdjointDerivative(u: *const u32, nu: usize, k: *const u32, nk: usize, seed: *const f64, ns: usize, sens: *mut f64, nsens: usize) => "not provided (providesAdjointDerivatives = false)";
    fmi3GetNumberOfVariableDependencies(r: u32, n: *mut usize) => "not provided (the model structure lists no dependencies)";
    fmi3GetVariableDependencies(r: u32, e: *mut usize, ind: *mut u32, ei: *mut usize, kinds: *mut c_int, n: usize) => "not provided (the model structure lists no dependencies)";
    fmi3ActivateModelPartition(clock: u32, time: f64) => "the FMU supports co-simulation only";
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: Fmi3Instance,
    currentCommunicationPoint: f64,
    communicationStepSize: f64,
    _noSetFMUStatePriorToCurrentPoint: Fmi3Boolean,
    eventHandlingNeeded: *mut Fmi3Boolean,
    terminateSimulation: *mut Fmi3Boolean,
    earlyReturn: *mut Fmi3Boolean,
    lastSuccessfulTime: *mut f64,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3DoStep", false, |i| {
        if eventHandlingNeeded.is_null()
            || terminateSimulation.is_null()
            || earlyReturn.is_null()
            || lastSuccessfulTime.is_null()
        {
            return i.error("fmi3DoStep: eventHandlingNeeded, terminateSimulation, earlyReturn and lastSuccessfulTime must not be NULL");
        }
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
                    &format!("fmi3DoStep: step discarded, the FMU stays at t = {last_successful_time} s: {reason}"),
                );
                Status::Discard
            }
            StepStatus::Error(e) => i.error(&format!("fmi3DoStep: {e}")),
        };
        // SAFETY: all four checked non-NULL above.
        unsafe {
            *eventHandlingNeeded = 0;
            *terminateSimulation = 0;
            *earlyReturn = 0;
            *lastSuccessfulTime = i.slave.plant().time();
        }
        i.last_step = status;
        status
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(
    instance: Fmi3Instance,
    FMUState: *mut Fmi3FmuState,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3GetFMUState", false, |i| {
        if FMUState.is_null() {
            return i.error("fmi3GetFMUState: FMUState is NULL");
        }
        let plant_state = i.slave.get_state();
        // SAFETY: non-NULL pointer to the importer's handle variable.
        let slot = unsafe { &mut *FMUState };
        // SAFETY: a non-NULL handle must be one of ours, to be overwritten.
        match unsafe { saved_state(*slot) } {
            Some(existing) => {
                existing.state = plant_state;
                existing.bytes = None;
            }
            None if slot.is_null() => {
                *slot = Box::into_raw(SavedState::new(plant_state)) as Fmi3FmuState
            }
            None => {
                return i
                    .error("fmi3GetFMUState: *FMUState is neither NULL nor a state of this FMU")
            }
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFMUState(
    instance: Fmi3Instance,
    FMUState: Fmi3FmuState,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3SetFMUState", false, |i| {
        // SAFETY: the handle is checked by its tag.
        let Some(s) = (unsafe { saved_state(FMUState) }) else {
            return i.error("fmi3SetFMUState: FMUState is NULL or not a state of this FMU");
        };
        let res = i.slave.set_state(&s.state);
        report(i, "fmi3SetFMUState", res)
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeFMUState(
    instance: Fmi3Instance,
    FMUState: *mut Fmi3FmuState,
) -> Fmi3Status {
    code(with_instance(instance, "fmi3FreeFMUState", true, |i| {
        if FMUState.is_null() {
            return i.error("fmi3FreeFMUState: FMUState is NULL");
        }
        // SAFETY: non-NULL pointer to the importer's handle; the handle is checked by its tag.
        unsafe {
            free_saved_state(*FMUState);
            *FMUState = std::ptr::null_mut();
        }
        Status::Ok
    }))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
    instance: Fmi3Instance,
    FMUState: Fmi3FmuState,
    size: *mut usize,
) -> Fmi3Status {
    code(with_instance(
        instance,
        "fmi3SerializedFMUStateSize",
        false,
        |i| {
            // SAFETY: the handle is checked by its tag.
            let (Some(s), false) = (unsafe { saved_state(FMUState) }, size.is_null()) else {
                return i.error("fmi3SerializedFMUStateSize: FMUState or size is NULL or invalid");
            };
            // SAFETY: non-NULL.
            unsafe { *size = s.bytes().len() };
            Status::Ok
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializeFMUState(
    instance: Fmi3Instance,
    FMUState: Fmi3FmuState,
    serializedState: *mut u8,
    size: usize,
) -> Fmi3Status {
    code(with_instance(
        instance,
        "fmi3SerializeFMUState",
        false,
        |i| {
            // SAFETY: the handle is checked by its tag.
            let Some(s) = (unsafe { saved_state(FMUState) }) else {
                return i
                    .error("fmi3SerializeFMUState: FMUState is NULL or not a state of this FMU");
            };
            let data = s.bytes();
            if size != data.len() {
                return i.error(&format!(
                "fmi3SerializeFMUState: size = {size}, but the state takes {} bytes (fmi3SerializedFMUStateSize)",
                data.len()
            ));
            }
            let Some(out) = slice_mut(serializedState, size) else {
                return i.error("fmi3SerializeFMUState: serializedState is NULL");
            };
            out.copy_from_slice(data);
            Status::Ok
        },
    ))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DeserializeFMUState(
    instance: Fmi3Instance,
    serializedState: *const u8,
    size: usize,
    FMUState: *mut Fmi3FmuState,
) -> Fmi3Status {
    code(with_instance(
        instance,
        "fmi3DeserializeFMUState",
        false,
        |i| {
            let (Some(data), false) = (slice(serializedState, size), FMUState.is_null()) else {
                return i.error("fmi3DeserializeFMUState: serializedState or FMUState is NULL");
            };
            match Slave::deserialize_state(data) {
                Ok(s) => {
                    // SAFETY: non-NULL pointer to the importer's handle variable, which receives a
                    // new state (its old content is not read: it may be uninitialised).
                    unsafe { *FMUState = Box::into_raw(SavedState::new(s)) as Fmi3FmuState };
                    Status::Ok
                }
                Err(e) => i.error(&format!("fmi3DeserializeFMUState: {e}")),
            }
        },
    ))
}

/// True if `instance` is in step mode (for tests and harnesses).
///
/// # Safety
/// As every entry point: NULL or a live instance.
pub unsafe fn in_step_mode(instance: Fmi3Instance) -> bool {
    let mut yes = false;
    with_instance(instance, "in_step_mode", true, |i| {
        yes = i.slave.lifecycle() == LifecycleState::StepMode;
        Status::Ok
    });
    yes
}
