//! What every example program shares: errors printed as one message line naming the input
//! (with the causes it does not already say under it) and exit status 1, never a debug dump.

use std::error::Error;
use std::process::ExitCode;

/// Run `body`; on an error print `program: message` and each cause the message does not
/// already contain, and return a failing exit status.
pub fn run(program: &str, body: impl FnOnce() -> Result<(), Box<dyn Error>>) -> ExitCode {
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{program}: {e}");
            let mut said = e.to_string();
            let mut cause = e.source();
            while let Some(c) = cause {
                let text = c.to_string();
                if !said.contains(&text) {
                    eprintln!("  caused by: {text}");
                    said.push_str(&text);
                }
                cause = c.source();
            }
            ExitCode::FAILURE
        }
    }
}

/// `error` as a message that names `path`: prefixed with it unless it already says it.
#[allow(dead_code)] // not every program reads a file whose errors lack its name
pub fn naming(path: &std::path::Path, error: impl std::fmt::Display) -> String {
    let shown = path.display().to_string();
    let message = error.to_string();
    if message.contains(&shown) {
        message
    } else {
        format!("{shown}: {message}")
    }
}

/// The folder an example writes its demo output to when not told otherwise:
/// `target/treemocap-demo/<program>/` (or under `$CARGO_TARGET_DIR`), one per program so
/// that no example overwrites another's files.
#[allow(dead_code)] // not every program writes demo output
pub fn demo_dir(program: &str) -> std::path::PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR").map_or_else(
        || std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target"),
        std::path::PathBuf::from,
    );
    target.join("treemocap-demo").join(program)
}

/// Progress of a long stage on stderr, one line rewritten in place at most twice a second.
#[allow(dead_code)] // not every program has long stages
pub struct ProgressLine {
    last: std::sync::Mutex<Option<std::time::Instant>>,
}

#[allow(dead_code)]
impl ProgressLine {
    /// A progress line that has printed nothing yet.
    pub fn new() -> Self {
        Self {
            last: std::sync::Mutex::new(None),
        }
    }

    /// Show `done` of `total` steps of `stage`.
    pub fn show(&self, stage: &str, done: usize, total: usize) {
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        let due = last.is_none_or(|t| t.elapsed().as_secs_f64() > 0.5);
        if done == total || due {
            *last = Some(std::time::Instant::now());
            eprint!(
                "\r{stage:<12} {done}/{total} ({:.0} %)   ",
                100.0 * done as f64 / total.max(1) as f64
            );
            if done == total {
                eprintln!();
            }
        }
    }
}
