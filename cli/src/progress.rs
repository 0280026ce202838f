//! The progress bar of long runs.

pub use indicatif::ProgressBar;
use indicatif::{ProgressDrawTarget, ProgressStyle};

/// A bar of `total` steps on stderr, labelled `what` (e.g. "simulating"). It is drawn only when
/// stderr is a terminal, so logs and pipes see nothing of it.
pub fn bar(total: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} {what} [{{bar:40}}] {{pos}}/{{len}} steps ({{eta}})"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}
