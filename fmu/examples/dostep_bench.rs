//! The FMU's `fmi3DoStep` cost per macro step against the in-process `Slave::do_step`, side by
//! side in one run: the shared library is loaded with `dlopen` from a packaged `.fmu`'s
//! `binaries/x86_64-linux/crawler_physics.so` (or any path given), as an importer loads it.
//!
//! ```sh
//! scripts/build-fmu.sh && unzip -o -d /tmp/fmu3 target/fmu/crawler_plant_fmi3.fmu
//! cargo run --release -p crawler-fmu --example dostep_bench -- /tmp/fmu3/binaries/x86_64-linux/crawler_physics.so
//! ```
//!
//! Each round runs `STEPS` macro steps on a fresh instance of each, alternating which goes first;
//! the figure is the median over rounds of the time per macro step. Prints JSON.

use std::ffi::{c_char, c_int, c_void, CString};
use std::time::Instant;

use crawler_physics::model_description::instantiation_token;
use crawler_physics::slave::StepStatus;

const STEPS: u32 = 2000;
const ROUNDS: usize = 7;

type Instantiate = unsafe extern "C" fn(
    *const c_char,
    *const c_char,
    *const c_char,
    u8,
    u8,
    u8,
    u8,
    *const u32,
    usize,
    *mut c_void,
    *const c_void,
    *const c_void,
) -> *mut c_void;
type Init = unsafe extern "C" fn(*mut c_void, u8, f64, f64, u8, f64) -> c_int;
type Exit = unsafe extern "C" fn(*mut c_void) -> c_int;
type DoStep =
    unsafe extern "C" fn(*mut c_void, f64, f64, u8, *mut u8, *mut u8, *mut u8, *mut f64) -> c_int;
type Free = unsafe extern "C" fn(*mut c_void);

struct Library {
    instantiate: Instantiate,
    init: Init,
    exit: Exit,
    do_step: DoStep,
    free: Free,
}

fn load(path: &str) -> Library {
    let c = CString::new(path).unwrap();
    // SAFETY: dlopen/dlsym on a library we built; the symbols have the FMI 3.0 signatures above.
    unsafe {
        let h = libc::dlopen(c.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL);
        assert!(!h.is_null(), "cannot load {path}");
        let sym = |name: &str| {
            let n = CString::new(name).unwrap();
            let p = libc::dlsym(h, n.as_ptr());
            assert!(!p.is_null(), "{name} missing in {path}");
            p
        };
        Library {
            instantiate: std::mem::transmute::<*mut c_void, Instantiate>(sym(
                "fmi3InstantiateCoSimulation",
            )),
            init: std::mem::transmute::<*mut c_void, Init>(sym("fmi3EnterInitializationMode")),
            exit: std::mem::transmute::<*mut c_void, Exit>(sym("fmi3ExitInitializationMode")),
            do_step: std::mem::transmute::<*mut c_void, DoStep>(sym("fmi3DoStep")),
            free: std::mem::transmute::<*mut c_void, Free>(sym("fmi3FreeInstance")),
        }
    }
}

fn fmu_round(lib: &Library, h: f64) -> f64 {
    let name = CString::new("bench").unwrap();
    let cells = crawler_fmu::defaults::scenario().plant.numerics.cells;
    let token = CString::new(instantiation_token(cells)).unwrap();
    // SAFETY: the FMI 3.0 calling sequence with valid arguments.
    unsafe {
        let i = (lib.instantiate)(
            name.as_ptr(),
            token.as_ptr(),
            std::ptr::null(),
            0,
            0,
            0,
            0,
            std::ptr::null(),
            0,
            std::ptr::null_mut(),
            std::ptr::null(),
            std::ptr::null(),
        );
        assert!(!i.is_null());
        assert_eq!((lib.init)(i, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!((lib.exit)(i), 0);
        let (mut a, mut b, mut c, mut t) = (0u8, 0u8, 0u8, 0.0);
        let start = Instant::now();
        for n in 0..STEPS {
            let s = (lib.do_step)(i, f64::from(n) * h, h, 1, &mut a, &mut b, &mut c, &mut t);
            assert_eq!(s, 0);
        }
        let took = start.elapsed().as_secs_f64();
        (lib.free)(i);
        took / f64::from(STEPS)
    }
}

fn slave_round(h: f64) -> f64 {
    let mut slave = crawler_fmu::defaults::slave("bench").unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.exit_initialization_mode().unwrap();
    let start = Instant::now();
    for n in 0..STEPS {
        assert_eq!(slave.do_step(f64::from(n) * h, h), StepStatus::Ok);
    }
    start.elapsed().as_secs_f64() / f64::from(STEPS)
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

fn main() {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/release/libcrawler_fmu.so".into());
    let lib = load(&path);
    let s = crawler_fmu::defaults::scenario();
    let d = s.plant.discretisation().unwrap();
    let (mut fmu, mut slave) = (Vec::new(), Vec::new());
    for round in 0..ROUNDS {
        if round % 2 == 0 {
            fmu.push(fmu_round(&lib, d.step));
            slave.push(slave_round(d.step));
        } else {
            slave.push(slave_round(d.step));
            fmu.push(fmu_round(&lib, d.step));
        }
    }
    let (f, s_) = (median(fmu), median(slave));
    println!(
        "{{\"library\": {:?}, \"cells\": {}, \"substeps\": {}, \"macro_steps_per_round\": {STEPS}, \"rounds\": {ROUNDS}, \
         \"fmu_do_step_us\": {:.3}, \"slave_do_step_us\": {:.3}, \"ratio\": {:.4}}}",
        path,
        s.plant.numerics.cells,
        d.substeps,
        f * 1e6,
        s_ * 1e6,
        f / s_
    );
}
