//! The comparison table of docs/feedback.md, in process (the same bits as `crawler compare`, by
//! the one-result rule): every case of `crawler compare` with every default policy and the
//! oracle, in task mode at each scenario's own resolution, t_end 60 s, two runs at a time.
//!
//! ```sh
//! cargo bench -p crawler-policies --bench comparison
//! ```
//!
//! The test `the_comparison_table_in_the_docs_is_what_the_policies_do_now` checks the docs' copy.

use crawler_policies::comparison::{in_process_table, table, CASES, POLICIES};

fn main() -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let rows = in_process_table(&CASES, &POLICIES, None, 60.0, 2)?;
    print!("{}", table(&rows));
    eprintln!(
        "{} runs in {:.0} s of wall time",
        rows.len(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
