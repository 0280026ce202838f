//! What both APIs share: the instance behind an FMI handle, its logger, the panic guard and the
//! checks of pointers and sizes.

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use crawler_physics::plant::PlantState;
use crawler_physics::slave::Slave;

/// FMI status codes, the same numbers in FMI 2.0 (`fmi2Status`) and FMI 3.0 (`fmi3Status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i32)]
pub enum Status {
    /// `fmiOK`.
    Ok = 0,
    /// `fmiWarning`.
    Warning = 1,
    /// `fmiDiscard`.
    Discard = 2,
    /// `fmiError`.
    Error = 3,
}

/// The FMI 2.0 logger: `void (*)(env, instanceName, status, category, message, ...)`.
pub type Fmi2Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, c_int, *const c_char, *const c_char, ...);

/// The FMI 3.0 logger: `void (*)(instanceEnvironment, status, category, message)`.
pub type Fmi3Logger = unsafe extern "C" fn(*mut c_void, c_int, *const c_char, *const c_char);

/// Where log messages go.
#[derive(Clone, Copy)]
pub enum Logger {
    /// FMI 2.0 callback (may be absent) and the component environment.
    Fmi2(Option<Fmi2Logger>, *mut c_void),
    /// FMI 3.0 callback (may be absent) and the instance environment.
    Fmi3(Option<Fmi3Logger>, *mut c_void),
}

/// Log categories (declared in the model descriptions).
pub mod category {
    /// Calls that failed, with the reason.
    pub const ERROR: &str = "logStatusError";
    /// Steps that were discarded.
    pub const DISCARD: &str = "logStatusDiscard";
    /// Calls that succeeded with a warning.
    pub const WARNING: &str = "logStatusWarning";
    /// Lifecycle and configuration (only with debug logging on).
    pub const EVENTS: &str = "logEvents";
    /// Every category.
    pub const ALL: [&str; 4] = [ERROR, DISCARD, WARNING, EVENTS];
}

/// Tag of a live instance (a stale or foreign pointer is refused instead of used).
const INSTANCE_TAG: u64 = 0x4352_574c_4649_4e53; // "CRWLFINS"
/// Tag of a live FMU state.
const STATE_TAG: u64 = 0x4352_574c_4653_5441; // "CRWLFSTA"

/// One FMU instance.
pub struct Instance {
    tag: u64,
    /// The plant.
    pub slave: Slave,
    name: CString,
    logger: Logger,
    /// Categories logged besides errors and discards (debug logging).
    debug: Vec<&'static str>,
    /// FMI 2.0 `SetupExperiment`: start time and stop time, applied at initialisation.
    pub setup: (f64, Option<f64>),
    /// Strings returned by `GetString`, valid until the next call.
    pub strings: Vec<CString>,
    /// Status of the last `DoStep`.
    pub last_step: Status,
    /// A call panicked: only `FreeInstance` and `Reset` are accepted.
    pub poisoned: bool,
}

impl Instance {
    /// A new instance around `slave`.
    pub fn new(slave: Slave, name: &str, logger: Logger, logging_on: bool) -> Box<Self> {
        let mut i = Box::new(Self {
            tag: INSTANCE_TAG,
            slave,
            name: c_string(name),
            logger,
            debug: Vec::new(),
            setup: (0.0, None),
            strings: Vec::new(),
            last_step: Status::Ok,
            poisoned: false,
        });
        i.set_debug_logging(logging_on, &[]);
        i
    }

    /// Turns debug logging on (for `categories`, all if empty) or off.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[String]) -> Status {
        self.debug.clear();
        if !on {
            return Status::Ok;
        }
        if categories.is_empty() {
            self.debug.extend(category::ALL);
            return Status::Ok;
        }
        for c in categories {
            match category::ALL.iter().find(|k| **k == c.as_str()) {
                Some(k) => self.debug.push(k),
                None => {
                    self.log(
                        Status::Warning,
                        category::WARNING,
                        &format!(
                            "unknown log category {c:?}: allowed {}",
                            category::ALL.join(", ")
                        ),
                    );
                    return Status::Warning;
                }
            }
        }
        Status::Ok
    }

    /// Sends a message to the importer's logger. Errors, discards and warnings are always sent;
    /// other messages only with debug logging on for their category.
    pub fn log(&self, status: Status, category: &str, message: &str) {
        let always = matches!(status, Status::Error | Status::Discard | Status::Warning);
        if !always && !self.debug.contains(&category) {
            return;
        }
        log_to(self.logger, &self.name, status, category, message);
    }

    /// Logs an error and returns `Status::Error`.
    pub fn error(&self, message: &str) -> Status {
        self.log(Status::Error, category::ERROR, message);
        Status::Error
    }
}

/// Sends one message to a logger (no instance needed: used when instantiation fails).
pub fn log_to(logger: Logger, name: &CStr, status: Status, category: &str, message: &str) {
    let category = c_string(category);
    let message = c_string(message);
    // SAFETY: the callbacks were given by the importer for exactly this use; every string is a
    // valid NUL-terminated C string that outlives the call. The FMI 2.0 logger is a printf-style
    // function: the message is passed as the argument of "%s", never as the format.
    unsafe {
        match logger {
            Logger::Fmi2(Some(f), env) => f(
                env,
                name.as_ptr(),
                status as c_int,
                category.as_ptr(),
                c"%s".as_ptr(),
                message.as_ptr(),
            ),
            Logger::Fmi3(Some(f), env) => {
                f(env, status as c_int, category.as_ptr(), message.as_ptr())
            }
            _ => {}
        }
    }
}

/// A C string of `s` (interior NULs replaced, so nothing is lost silently but the string stays
/// valid).
pub fn c_string(s: &str) -> CString {
    CString::new(s.replace('\0', "\\0")).expect("no interior NUL left")
}

/// The text of a C string argument: `Err(what is wrong)` if NULL, not UTF-8 or empty (when
/// `nonempty`).
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string.
pub unsafe fn text<'a>(p: *const c_char, what: &str, nonempty: bool) -> Result<&'a str, String> {
    if p.is_null() {
        return Err(format!("{what} is NULL"));
    }
    // SAFETY: non-NULL and NUL-terminated per the FMI contract.
    let s = unsafe { CStr::from_ptr(p) }
        .to_str()
        .map_err(|_| format!("{what} is not UTF-8"))?;
    if nonempty && s.is_empty() {
        return Err(format!("{what} is empty"));
    }
    Ok(s)
}

/// The slice behind an FMI array argument of `n` elements: `None` if `p` is NULL while `n > 0`
/// or the size overflows.
///
/// # Safety
/// If not NULL, `p` points to `n` initialised elements valid for the call.
pub unsafe fn slice<'a, T>(p: *const T, n: usize) -> Option<&'a [T]> {
    if n == 0 {
        return Some(&[]);
    }
    if p.is_null() || n.checked_mul(std::mem::size_of::<T>())? > isize::MAX as usize {
        return None;
    }
    // SAFETY: checked above; validity is the caller's contract.
    Some(unsafe { std::slice::from_raw_parts(p, n) })
}

/// The mutable slice behind an FMI output array of `n` elements (see [`slice`]).
///
/// # Safety
/// If not NULL, `p` points to `n` writable elements valid for the call.
pub unsafe fn slice_mut<'a, T>(p: *mut T, n: usize) -> Option<&'a mut [T]> {
    if n == 0 {
        return Some(&mut []);
    }
    if p.is_null() || n.checked_mul(std::mem::size_of::<T>())? > isize::MAX as usize {
        return None;
    }
    // SAFETY: checked above; validity is the caller's contract.
    Some(unsafe { std::slice::from_raw_parts_mut(p, n) })
}

/// Runs `f` and turns a panic into `fallback`.
pub fn guard<R>(fallback: R, f: impl FnOnce() -> R) -> R {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(fallback)
}

/// Runs `f` on the instance behind `c` inside the panic guard: `Error` if `c` is NULL, not a
/// live instance, or poisoned by an earlier panic (unless `even_poisoned`); a panic in `f`
/// poisons the instance and returns `Error`.
///
/// # Safety
/// `c` is NULL or a pointer returned by this library's instantiate and not yet freed (a freed
/// or foreign pointer is detected by its tag on a best-effort basis only).
pub unsafe fn with_instance(
    c: *mut c_void,
    call: &str,
    even_poisoned: bool,
    f: impl FnOnce(&mut Instance) -> Status,
) -> Status {
    let inst = c as *mut Instance;
    if inst.is_null() {
        return Status::Error;
    }
    // SAFETY: see the function's contract; the tag is read before anything else is used.
    if unsafe { (*inst).tag } != INSTANCE_TAG {
        return Status::Error;
    }
    // SAFETY: a live instance (tag checked); FMI calls on one instance are not concurrent.
    let this = unsafe { &mut *inst };
    if this.poisoned && !even_poisoned {
        return this.error(&format!(
            "{call}: an earlier call failed inside the FMU (a bug, reported above); \
             only Reset and FreeInstance are accepted"
        ));
    }
    match catch_unwind(AssertUnwindSafe(|| f(&mut *this))) {
        Ok(s) => s,
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            // SAFETY: as above; `f` has returned (by unwinding), so no other borrow is live.
            let this = unsafe { &mut *inst };
            this.poisoned = true;
            this.error(&format!("{call}: internal error in the FMU: {what}"))
        }
    }
}

/// Frees an instance (valid in every state; NULL and foreign pointers are ignored).
///
/// # Safety
/// `c` is NULL or a live instance of this library; it is not used afterwards.
pub unsafe fn free_instance(c: *mut c_void) {
    let inst = c as *mut Instance;
    if inst.is_null() {
        return;
    }
    // SAFETY: the tag is checked before the box is reclaimed; then cleared so that a second
    // FreeInstance of the same pointer is more likely to be noticed.
    unsafe {
        if (*inst).tag != INSTANCE_TAG {
            return;
        }
        (*inst).tag = 0;
        let boxed = Box::from_raw(inst);
        let _ = catch_unwind(AssertUnwindSafe(move || drop(boxed)));
    }
}

/// A saved FMU state: the plant's complete state and, once asked for, its serialised bytes.
pub struct SavedState {
    tag: u64,
    /// The state.
    pub state: PlantState,
    /// `Slave::serialize_state` of it, made on the first request for its size or bytes.
    pub bytes: Option<Vec<u8>>,
}

impl SavedState {
    /// A new handle for `state`.
    pub fn new(state: PlantState) -> Box<Self> {
        Box::new(Self {
            tag: STATE_TAG,
            state,
            bytes: None,
        })
    }

    /// The serialised bytes.
    pub fn bytes(&mut self) -> &[u8] {
        let state = &self.state;
        self.bytes
            .get_or_insert_with(|| Slave::serialize_state(state))
    }
}

/// The saved state behind a handle, or `None` if NULL or not a live state of this library.
///
/// # Safety
/// `p` is NULL or a handle returned by this library's GetFMUState/DeserializeFMUState and not
/// yet freed.
pub unsafe fn saved_state<'a>(p: *mut c_void) -> Option<&'a mut SavedState> {
    let s = p as *mut SavedState;
    // SAFETY: see the contract; the tag is checked before use.
    unsafe { (!s.is_null() && (*s).tag == STATE_TAG).then(|| &mut *s) }
}

/// Frees a saved state handle (NULL and foreign pointers are ignored).
///
/// # Safety
/// As [`saved_state`]; the handle is not used afterwards.
pub unsafe fn free_saved_state(p: *mut c_void) {
    // SAFETY: as for `saved_state`.
    unsafe {
        if saved_state(p).is_some() {
            let s = p as *mut SavedState;
            (*s).tag = 0;
            drop(Box::from_raw(s));
        }
    }
}

/// Why this CPU cannot run the library, if it cannot (the build targets x86-64-v3).
pub fn cpu_refusal() -> Option<String> {
    crawler_physics::cpu::missing_features().map(|m| {
        format!("{m} (for an FMU that runs on any x86-64 CPU: scripts/build-fmu.sh --portable)")
    })
}
