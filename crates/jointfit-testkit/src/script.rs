//! Runs the oracle scripts of `scripts/` with the Python interpreter of `$JOINTFIT_PYTHON`.
//!
//! The scripts print their results on lines starting with `@@` (anything else is log output):
//! a JSON document (`osim_check.py`) or tab-separated fields (`opensim_oracle.py`).

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use serde_json::Value;

/// Oracle scripts the command line ships (embedded in the binary for `bench`): they live
/// beside its sources, in `crates/jointfit-cli/assets/`.
const SHIPPED: &[&str] = &["osim_check.py"];

/// `scripts/NAME` of the repository, or `crates/jointfit-cli/assets/NAME` for a script the
/// command line ships.
pub fn script_path(name: &str) -> PathBuf {
    let dir = match SHIPPED.contains(&name) {
        true => "../jointfit-cli/assets",
        false => "../../scripts",
    };
    Path::new(env!("CARGO_MANIFEST_DIR")).join(dir).join(name)
}

/// One run of a script: `python scripts/NAME ARGS…`, optionally with text on stdin and in a
/// working directory.
#[derive(Debug)]
pub struct Script {
    python: PathBuf,
    name: String,
    args: Vec<String>,
    stdin: Option<String>,
    cwd: Option<PathBuf>,
}

impl Script {
    /// `python scripts/NAME`.
    pub fn new(python: &Path, name: &str) -> Script {
        Script {
            python: python.to_path_buf(),
            name: name.to_string(),
            args: Vec::new(),
            stdin: None,
            cwd: None,
        }
    }

    /// Appends command-line arguments.
    pub fn args<S: AsRef<str>>(mut self, args: &[S]) -> Script {
        self.args
            .extend(args.iter().map(|a| a.as_ref().to_string()));
        self
    }

    /// Text written to the script's stdin (then closed).
    pub fn stdin(mut self, text: String) -> Script {
        self.stdin = Some(text);
        self
    }

    /// The script's working directory.
    pub fn current_dir(mut self, dir: &Path) -> Script {
        self.cwd = Some(dir.to_path_buf());
        self
    }

    /// Runs the script to the end and returns its stdout.
    ///
    /// # Panics
    /// When the interpreter cannot be started or the script exits with an error (the message
    /// carries its stderr and stdout).
    pub fn run(self) -> String {
        let mut cmd = Command::new(&self.python);
        cmd.arg(script_path(&self.name))
            .args(&self.args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if let Some(dir) = &self.cwd {
            cmd.current_dir(dir);
        }
        let mut child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("cannot run {}: {e}", self.python.display()));
        {
            let mut stdin = child.stdin.take().expect("stdin is piped");
            if let Some(text) = &self.stdin {
                stdin
                    .write_all(text.as_bytes())
                    .unwrap_or_else(|e| panic!("{}: writing stdin: {e}", self.name));
            }
        }
        let out = child
            .wait_with_output()
            .unwrap_or_else(|e| panic!("{}: {e}", self.name));
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{} {:?} failed: {}\n{stdout}",
            self.name,
            self.args,
            String::from_utf8_lossy(&out.stderr)
        );
        stdout
    }

    /// Runs the script and parses its first `@@` line as JSON.
    ///
    /// # Panics
    /// As [`Script::run`], and when no `@@` line is printed or it is not JSON.
    pub fn run_json(self) -> Value {
        let label = format!("{} {:?}", self.name, self.args);
        let stdout = self.run();
        let line = result_lines(&stdout)
            .next()
            .unwrap_or_else(|| panic!("{label} printed no result: {stdout}"));
        serde_json::from_str(line).unwrap_or_else(|e| panic!("{label}: result is not JSON: {e}"))
    }
}

/// The result lines of a script's output, without their `@@` prefix.
pub fn result_lines(stdout: &str) -> impl Iterator<Item = &str> {
    stdout.lines().filter_map(|l| l.strip_prefix("@@"))
}

/// `osim_check.py MODE` with `request` as JSON on stdin, in `cwd` when given: the
/// OpenSim 4.6 oracle of the `.osim` export and of inverse kinematics.
pub fn osim_check(python: &Path, mode: &str, request: &Value, cwd: Option<&Path>) -> Value {
    let mut s = Script::new(python, "osim_check.py")
        .args(&[mode])
        .stdin(request.to_string());
    if let Some(dir) = cwd {
        s = s.current_dir(dir);
    }
    s.run_json()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn result_lines_keep_only_the_marked_lines() {
        let out = "log\n@@{\"a\": 1}\nmore log\n@@x\ty\n";
        assert_eq!(
            result_lines(out).collect::<Vec<_>>(),
            ["{\"a\": 1}", "x\ty"]
        );
    }

    #[test]
    fn scripts_exist() {
        for name in ["osim_check.py", "opensim_oracle.py"] {
            assert!(script_path(name).is_file(), "{name}");
        }
    }
}
