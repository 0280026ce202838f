//! The plant's report on the wire: the one place where the plant library's report becomes the
//! protocol's.

use crawler_facts::{Metric, MetricValues};
use crawler_physics::report::Report;
use crawler_protocol::{EpisodeStats, FinalReport, ProtocolError, ReportWindow, TaskResult};

/// The report on the wire: the plant's `finished` status carries this conversion of its report,
/// the one place where the library's report becomes the protocol's. The episode list stays out
/// (the events stream carried every episode); a mileage or a momentum residual that is not a
/// number (P = 0, a body at rest) travels as `None`; a scenario name longer than the protocol
/// allows is cut at a character boundary. Anything else not finite or out of range is refused,
/// naming the field.
pub fn wire_report(r: &Report) -> Result<FinalReport, ProtocolError> {
    {
        let number = |x: f64| Some(x).filter(|x| x.is_finite());
        let mut scenario = r.scenario.clone();
        while scenario.len() > crawler_protocol::MAX_SCENARIO_NAME_LEN {
            scenario.pop();
        }
        let task = r.task.as_ref().map(|t| TaskResult {
            outcome: t.outcome,
            distance_target: t.distance_target,
            distance: t.distance,
            time_to_distance: t.time_to_distance,
            energy_budget: t.energy_budget,
            energy_used: t.energy_used,
            energy_at_distance: t.energy_at_distance,
            energy_exhausted_at: t.energy_exhausted_at,
            sigma_max: t.sigma_max,
            max_stress: t.max_stress,
            time_over_sigma_max: t.time_over_sigma_max,
            stress_tolerance: t.stress_tolerance,
            stress_exceeded_at: t.stress_exceeded_at,
            run_time: t.run_time,
        });
        // Every metric as it is (a value that is not finite is refused by name below), but the
        // mileage, which is not a number when no power was put in.
        let mut values = MetricValues::NONE;
        for m in Metric::ALL {
            let x = r.value(m);
            let kept = m != Metric::Mileage || x.is_finite();
            values = values.with_raw(m, kept.then_some(x));
        }
        let report = FinalReport {
            scenario,
            values,
            dissipation: r.dissipation,
            identity_velocity: r.identity_velocity,
            momentum_residual: number(r.momentum_residual),
            events: EpisodeStats {
                count: r.events.count,
                per_node_per_period: r.events.per_node_per_period,
                mean_duration: r.events.mean_duration,
                min_duration: r.events.min_duration,
            },
            window: ReportWindow {
                start: r.window.start,
                end: r.window.end,
                periods: r.window.periods,
                steady: r.window.steady,
                whole_run: r.window.whole_run,
            },
            cells: r.cells as u64,
            dt: r.dt,
            step: r.parameters.step,
            courant: r.parameters.courant,
            dx: r.parameters.dx,
            cells_per_wavelength: r.parameters.cells_per_wavelength,
            steps: r.steps,
            macro_steps: r.macro_steps,
            t_end: r.t_end,
            state_digest: r.state_digest.clone(),
            task,
        };
        report.validate()?;
        Ok(report)
    }
}
