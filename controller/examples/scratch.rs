use crawler_controller::closed_loop;
use crawler_controller::controller::{Context, FeedbackOptions, PolicyOptions};
use crawler_controller::policies;
use crawler_plant::scenario::{Overrides, Scenario};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let file = &args[1];
    let policy = &args[2];
    let mut ov = Overrides::default();
    ov.end_run = Some(true);
    let mut sc = Scenario::from_file(std::path::Path::new(file), &ov)?;
    if let Some(t) = args.get(3) { sc.t_end = t.parse()?; }
    let mut fb = FeedbackOptions::default();
    for kv in args.iter().skip(4) {
        let (k, v) = kv.split_once('=').unwrap();
        let v: f64 = v.parse()?;
        if let Some(k) = k.strip_prefix("r.") { fb.reflex.set(k, v)?; } else { fb.adaptive.set(k, v)?; }
    }
    let ctx = Context::as_told(&sc, PolicyOptions::default(), fb)?;
    let t0 = std::time::Instant::now();
    let mut p = policies::build(policy, &ctx)?;
    eprintln!("{} ({:.2} s)", p.describe(), t0.elapsed().as_secs_f64());
    let t0 = std::time::Instant::now();
    let r = closed_loop::run(&sc, p.as_mut())?;
    for (n, i) in &r.insights { if i.text.contains("re-plan") || n % 5000 == 0 { println!("{n}: {}", i.text); } }
    println!("{}", r.report.task.as_ref().unwrap().summary());
    println!("steps {} wall {:.2} s", r.steps, t0.elapsed().as_secs_f64());
    Ok(())
}
