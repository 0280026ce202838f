//! What a crawler could sense: the observation's fields, per segment or one number.

use crawler_physics::execution::Observation;
use crawler_physics::params::Boundary;
use crawler_physics::scenario::Scenario;
use crawler_physics::sums::span_sums;
use crawler_policies::Context;

/// The sensed fields: name, per segment (else one number), lower bound, what it is.
pub const FIELDS: [(&str, bool, f64, &str); 9] = [
    (
        "strain",
        true,
        f64::NEG_INFINITY,
        "mean strain u_x of each segment (dimensionless)",
    ),
    (
        "stuck",
        true,
        0.0,
        "share of each segment's nodes held by static friction, in [0, 1]",
    ),
    (
        "stress",
        true,
        f64::NEG_INFINITY,
        "mean tension of each segment over A_c sigma_max",
    ),
    (
        "velocity",
        true,
        f64::NEG_INFINITY,
        "mean velocity of each segment, m/s",
    ),
    (
        "speed",
        false,
        f64::NEG_INFINITY,
        "mean speed of the body over the last step, m/s",
    ),
    (
        "progress",
        false,
        f64::NEG_INFINITY,
        "distance travelled by the centre of mass over D",
    ),
    (
        "energy",
        false,
        f64::NEG_INFINITY,
        "net actuator work so far over J0",
    ),
    (
        "power",
        false,
        f64::NEG_INFINITY,
        "input power over the last step, W",
    ),
    (
        "time",
        false,
        0.0,
        "time since the start over the scenario's t_end",
    ),
];

/// The context of a controller whose scenario (plant as told) is `told` (as `Context::new`).
pub fn context_of_told(told: &Scenario) -> Context {
    let p = &told.plant;
    Context {
        body: p.body,
        friction: p.friction,
        length: p.length,
        boundary: p.boundary,
        cells: p.numerics.cells,
        step: p.numerics.step,
        scenario: told.clone(),
    }
}

/// The first cell of each of `segments` segments of `cells` cells, and the end.
pub(super) fn segment_bounds(cells: usize, segments: usize) -> Vec<usize> {
    (0..=segments).map(|j| j * cells / segments).collect()
}

/// What a crawler senses, from the observations a controller gets at every communication step.
#[derive(Debug, Clone)]
pub struct Sensor {
    pub(super) fields: Vec<usize>,
    pub(super) bounds: Vec<usize>,
    pub(super) dx: f64,
    pub(super) boundary: Boundary,
    pub(super) step: f64,
    pub(super) area: f64,
    pub(super) distance_target: f64,
    pub(super) energy_budget: f64,
    pub(super) sigma_max: f64,
    pub(super) t_end: f64,
    pub(super) start: Option<(u64, f64, f64)>,
    pub(super) energy: f64,
}

impl Sensor {
    /// The sensor of `fields` (names of [`FIELDS`]) over `segments` segments, for a controller
    /// told `ctx`.
    pub fn new(ctx: &Context, fields: &[String], segments: usize) -> Result<Self, String> {
        if segments == 0 || segments > ctx.cells {
            return Err(format!(
                "segments = {segments}: allowed 1 to {} (the cells)",
                ctx.cells
            ));
        }
        let mut idx = Vec::new();
        for f in fields {
            match FIELDS.iter().position(|(n, ..)| n == f) {
                Some(i) if !idx.contains(&i) => idx.push(i),
                Some(_) => {
                    return Err(format!(
                        "fields: {f:?}: allowed each field once (given twice)"
                    ))
                }
                None => {
                    return Err(format!(
                        "fields: {f:?}: allowed {}",
                        FIELDS.iter().map(|f| f.0).collect::<Vec<_>>().join(", ")
                    ))
                }
            }
        }
        if idx.is_empty() {
            return Err("fields: none: allowed at least one field".into());
        }
        let s = &ctx.scenario;
        Ok(Self {
            fields: idx,
            bounds: segment_bounds(ctx.cells, segments),
            dx: ctx.length / ctx.cells as f64,
            boundary: ctx.boundary,
            step: ctx.step,
            area: ctx.body.area,
            distance_target: s.task.distance,
            energy_budget: s.task.energy,
            sigma_max: s.task.sigma_max,
            t_end: s.t_end,
            start: None,
            energy: 0.0,
        })
    }

    /// Numbers per observation.
    pub fn dim(&self) -> usize {
        let n = self.bounds.len() - 1;
        self.fields
            .iter()
            .map(|&i| if FIELDS[i].1 { n } else { 1 })
            .sum()
    }

    /// Lower bounds of the observation's entries.
    pub fn low(&self) -> Vec<f64> {
        let n = self.bounds.len() - 1;
        self.fields
            .iter()
            .flat_map(|&i| std::iter::repeat_n(FIELDS[i].2, if FIELDS[i].1 { n } else { 1 }))
            .collect()
    }

    /// Upper bounds of the observation's entries.
    pub fn high(&self) -> Vec<f64> {
        let n = self.bounds.len() - 1;
        self.fields
            .iter()
            .flat_map(|&i| {
                let hi = if FIELDS[i].0 == "stuck" {
                    1.0
                } else {
                    f64::INFINITY
                };
                std::iter::repeat_n(hi, if FIELDS[i].1 { n } else { 1 })
            })
            .collect()
    }

    /// The entries' names (`strain[3]`, `speed`, ...).
    pub fn names(&self) -> Vec<String> {
        let n = self.bounds.len() - 1;
        self.fields
            .iter()
            .flat_map(|&i| {
                let name = FIELDS[i].0;
                if FIELDS[i].1 {
                    (0..n).map(|j| format!("{name}[{j}]")).collect::<Vec<_>>()
                } else {
                    vec![name.to_string()]
                }
            })
            .collect()
    }

    /// Takes the observation of a communication step (every step, in order): its input power
    /// over the last step is added to the energy spent (as the task counts it, `P H`).
    pub fn feed(&mut self, step: u64, u: &[f64], input_power: f64) {
        match self.start {
            None => {
                let mean = u.iter().sum::<f64>() / u.len() as f64;
                self.start = Some((step, mean, 0.0));
            }
            Some(_) => self.energy += input_power * self.step,
        }
    }

    /// The observation's numbers for the state `obs` (fed already). `travelled`: the distance
    /// the centre of mass has travelled since the first observation fed, m, when the caller
    /// has it (the task's, the same subtraction of the same means), else computed from `obs.u`.
    pub fn encode(&self, obs: &Observation<'_>, travelled: Option<f64>, out: &mut Vec<f64>) {
        let n = self.bounds.len() - 1;
        let (start_step, start_pos, _) = self.start.unwrap_or((obs.step, 0.0, 0.0));
        let cells = obs.u.len();
        for &f in &self.fields {
            let first = out.len();
            match FIELDS[f].0 {
                "strain" => {
                    let u = obs.u;
                    let last = cells.saturating_sub(1);
                    out.resize(first + n, 0.0);
                    // the faces i in a..b with a next node (a free body's last has none)
                    let faces = |j: usize| {
                        let a = self.bounds[j];
                        (a, self.bounds[j + 1].min(last).max(a))
                    };
                    span_sums::<true>(u, faces, 0.0, &mut out[first..]);
                    for (j, sum) in out[first..].iter_mut().enumerate() {
                        let (a, inner) = faces(j);
                        let mut count = inner - a;
                        if self.bounds[j + 1] > inner && self.boundary == Boundary::Periodic {
                            // a periodic body's last face wraps around to u[0]
                            *sum += u[0] - u[cells - 1];
                            count += 1;
                        }
                        *sum = if count > 0 {
                            *sum / (count as f64 * self.dx)
                        } else {
                            0.0
                        };
                    }
                }
                "stuck" => {
                    for j in 0..n {
                        let (a, b) = (self.bounds[j], self.bounds[j + 1]);
                        let s = obs.stuck[a..b].iter().filter(|&&x| x).count();
                        out.push(s as f64 / (b - a) as f64);
                    }
                }
                "stress" => {
                    let scale = 1.0 / (self.area * self.sigma_max);
                    self.means(obs.tension, out);
                    out[first..].iter_mut().for_each(|m| *m *= scale);
                }
                "velocity" => self.means(obs.vel, out),
                "speed" => out.push(obs.mean_speed),
                "progress" => {
                    let d = travelled
                        .unwrap_or_else(|| obs.u.iter().sum::<f64>() / cells as f64 - start_pos);
                    out.push(d / self.distance_target);
                }
                "energy" => out.push(self.energy / self.energy_budget),
                "power" => out.push(obs.input_power),
                "time" => out.push((obs.step - start_step) as f64 * self.step / self.t_end),
                _ => unreachable!("a field of the table"),
            }
        }
    }

    /// Pushes each segment's mean of `values` (one per cell): its sum in order over the count.
    fn means(&self, values: &[f64], out: &mut Vec<f64>) {
        let first = out.len();
        let n = self.bounds.len() - 1;
        out.resize(first + n, 0.0);
        // `Iterator::sum` of f64 starts from -0.0: the same bits as `values[a..b].iter().sum()`
        let cells = |j: usize| (self.bounds[j], self.bounds[j + 1]);
        span_sums::<false>(values, cells, -0.0, &mut out[first..]);
        for (j, m) in out[first..].iter_mut().enumerate() {
            *m /= (self.bounds[j + 1] - self.bounds[j]) as f64;
        }
    }
}

/// The fields observed when none are named.
pub fn default_fields() -> Vec<String> {
    ["strain", "stuck", "stress", "speed", "progress", "energy"]
        .iter()
        .map(|s| s.to_string())
        .collect()
}
