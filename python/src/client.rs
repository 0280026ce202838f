//! The co-simulation client: `crawler_controller::client::run_with` (the credential, the seals,
//! the join and the exactly-once answering of the Rust controller), with a Python policy or a
//! registered one. One implementation of the wire: nothing of it is written again in Python.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use pyo3::prelude::*;

use crawler_controller::client::{run_with, BuildPolicy, ClientOptions, ClientOutcome, Interrupt};
use crawler_physics::scenario::Scenario;
use crawler_policies::Params;
use crawler_transport::NetworkArgs;

use crate::policy::PyPolicy;
use crate::scenario::PyScenario;
use crate::{any_error, input_error, invalid, run_error};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(control, m)?)?;
    Ok(())
}

/// Controls the co-simulation run `run_id` with `policy` (a registered name with `params`, or a
/// Python object with `act(observation)`) until the run ends: waits for the plant, joins, answers
/// every state exactly once. Returns the final summary as JSON; raises `RunError` (with the
/// controller's exit code) when the run ended otherwise.
#[pyfunction]
#[pyo3(signature = (policy, run_id=None, endpoint=None, credential=None, no_auth=false,
                    zenoh_config=None, scenario=None, params=Vec::new(), wait_timeout=60.0))]
#[allow(clippy::too_many_arguments)]
fn control(
    py: Python<'_>,
    policy: &Bound<'_, PyAny>,
    run_id: Option<String>,
    endpoint: Option<String>,
    credential: Option<PathBuf>,
    no_auth: bool,
    zenoh_config: Option<PathBuf>,
    scenario: Option<PyRef<'_, PyScenario>>,
    params: Vec<String>,
    wait_timeout: f64,
) -> PyResult<String> {
    if !(wait_timeout.is_finite() && wait_timeout > 0.0 && wait_timeout < 1e9) {
        return Err(invalid(
            py,
            "wait_timeout",
            &wait_timeout.to_string(),
            "a number of seconds, 0 < wait_timeout < 1e9",
        ));
    }
    if credential.is_some() && no_auth {
        return Err(invalid(
            py,
            "no_auth",
            "True",
            "False when a credential is given",
        ));
    }
    let network = NetworkArgs {
        run_id,
        endpoint,
        zenoh_config,
        credential,
        no_auth,
    }
    .network()
    .map_err(|e| input_error(py, e))?;
    let scenario: Scenario = match scenario {
        Some(s) => s.inner.clone(),
        None => Scenario::paper(),
    };
    let (name, parsed) = match policy.extract::<String>() {
        Ok(name) => {
            let p = crate::policy::checked_params(py, &name, &params)?;
            (Some(name), p)
        }
        Err(_) => (None, Params::default()),
    };
    let opts = ClientOptions {
        policy: name.clone().unwrap_or_else(|| "python".into()),
        params: parsed.clone(),
        scenario,
        network,
        wait_timeout: Duration::from_secs_f64(wait_timeout),
        take_over: None,
        stall: None,
    };
    let (tx, rx) = crossbeam_channel::unbounded::<Interrupt>();
    let object = policy.clone().unbind();
    let errors = Arc::new(Mutex::new(None::<PyErr>));
    let slot = errors.clone();
    let on_error = tx.clone();
    let build: BuildPolicy<'static> = match name {
        Some(n) => Box::new(move |ctx| crawler_policies::build(&n, ctx, &parsed)),
        None => Box::new(move |ctx| {
            let mut p = Python::attach(|py| PyPolicy::new(py, object, ctx))
                .map_err(|e| anyhow::anyhow!("the Python policy's reset failed: {e}"))?;
            p.on_error = Some(on_error);
            p.keep_errors_in(slot);
            Ok(Box::new(p))
        }),
    };
    let outcome = crate::sweep::interruptible(py, move |flag| {
        // Ctrl-C in Python sets the flag; the client stops on its interrupt channel
        let (done_tx, done_rx) = crossbeam_channel::bounded::<()>(1);
        std::thread::scope(|s| {
            s.spawn(|| loop {
                if flag.load(std::sync::atomic::Ordering::SeqCst) {
                    let _ = tx.send(Interrupt);
                    return;
                }
                if done_rx.recv_timeout(Duration::from_millis(50)).is_ok() {
                    return;
                }
            });
            let r = run_with(opts, build, rx);
            let _ = done_tx.send(());
            r
        })
    })?;
    let raised = errors.lock().ok().and_then(|mut e| e.take());
    if let Some(e) = raised {
        return Err(e);
    }
    match outcome.map_err(|e| any_error(py, e))? {
        // another controller took the run over: this one's part ended cleanly (the summary says
        // at which step and to whom)
        ClientOutcome::Finished(summary) | ClientOutcome::HandedOver(summary) => {
            crate::to_json(py, &summary)
        }
        ClientOutcome::Ended { reason, exit } => {
            let err = run_error(py, format!("the run ended: {reason}"));
            let _ = err.value(py).setattr("exit_code", exit.code());
            Err(err)
        }
    }
}
