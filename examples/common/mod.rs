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
