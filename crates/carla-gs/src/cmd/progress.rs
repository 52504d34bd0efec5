//! Progress bars shared by subcommands (hidden automatically when stderr is not a terminal).
use indicatif::{ProgressBar, ProgressStyle};

/// A byte-counting bar for reading inputs.
pub fn bytes_bar(message: &'static str) -> ProgressBar {
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {bytes}/{total_bytes} ({eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(message);
    pb
}

/// A counting bar for work items.
pub fn count_bar(message: &'static str) -> ProgressBar {
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message(message);
    pb
}
