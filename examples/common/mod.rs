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
