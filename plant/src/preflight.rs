//! What a user should know about a run before it starts: where it really ends and what it
//! costs. Printed by `crawler-plant simulate`, `run` and `run --check`.

use crawler_physics::scenario::Scenario;

/// A conservative single-thread rate of the stepping loop, cell updates per second
/// (docs/benchmarks.md measures 4e8 to 5e8 on one core of the development machine).
pub const NOMINAL_RATE: f64 = 2e8;

/// Runs estimated to take longer than this, s, are announced with their cost.
pub const ANNOUNCE_AFTER: f64 = 10.0;

/// Notes about `scenario`'s run, one line each: the end time when `t_end` is not a whole number
/// of communication steps, and the run's cost when it is long.
pub fn notes(scenario: &Scenario) -> Vec<String> {
    let Ok(size) = scenario.run_size() else {
        return Vec::new();
    };
    let mut notes = Vec::new();
    if (size.t_end - scenario.t_end).abs() > 1e-9 * scenario.t_end {
        notes.push(format!(
            "the run ends at t = {:.9} s, the first communication point at or after t_end = {} s \
             ({} communication steps of H = {:.6e} s; H is a whole number of internal steps)",
            size.t_end, scenario.t_end, size.macro_steps, size.step
        ));
    }
    let seconds = size.cell_updates / NOMINAL_RATE;
    if seconds > ANNOUNCE_AFTER {
        notes.push(format!(
            "{} cells x {} internal steps = {:.2e} cell updates: about {} on one core \
             (at {NOMINAL_RATE:.0e} cell updates/s; fewer cells or a shorter t_end make it shorter)",
            scenario.plant.numerics.cells,
            size.internal_steps,
            size.cell_updates,
            duration(seconds)
        ));
    }
    notes.extend(scenario.caveats().iter().map(|c| format!("warning: {c}")));
    notes
}

/// A duration for people: seconds, minutes, hours or days.
pub fn duration(seconds: f64) -> String {
    match seconds {
        s if s < 120.0 => format!("{s:.0} s"),
        s if s < 7200.0 => format!("{:.0} min", s / 60.0),
        s if s < 172_800.0 => format!("{:.1} h", s / 3600.0),
        s => format!("{:.1} days", s / 86_400.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario(cells: usize, t_end: f64, step: Option<f64>) -> Scenario {
        let mut s = Scenario::paper();
        s.plant.numerics.cells = cells;
        if let Some(h) = step {
            s.plant.numerics.step = h;
        }
        s.t_end = t_end;
        s
    }

    #[test]
    fn a_t_end_between_communication_points_is_announced_with_the_real_end() {
        let s = scenario(64, 1.0, Some(0.3));
        let size = s.run_size().unwrap();
        // 1.0 s is not a multiple of H (about 0.3 s): the run ends at the next point
        assert!(size.t_end > 1.0 && size.t_end < 1.0 + size.step);
        let said = notes(&s);
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].contains("the run ends at t = "), "{}", said[0]);
        assert!(said[0].contains(&format!("{:.9}", size.t_end)));
    }

    #[test]
    fn a_long_run_is_announced_with_its_cost() {
        let s = scenario(1 << 20, 100.0, None);
        let size = s.run_size().unwrap();
        assert_eq!(
            size.cell_updates,
            (1u64 << 20) as f64 * size.internal_steps as f64
        );
        let said = notes(&s);
        let cost = said.iter().find(|n| n.contains("cell updates")).unwrap();
        assert!(cost.contains("1048576 cells"), "{cost}");
        assert!(cost.contains("days") || cost.contains(" h "), "{cost}");
        // a short run says nothing
        assert!(notes(&scenario(64, 2.0, None))
            .iter()
            .all(|n| !n.contains("cell updates")));
    }

    #[test]
    fn durations_read_naturally() {
        assert_eq!(duration(30.0), "30 s");
        assert_eq!(duration(600.0), "10 min");
        assert_eq!(duration(3.0 * 3600.0), "3.0 h");
        assert_eq!(duration(86_400.0 * 40.0), "40.0 days");
    }
}
