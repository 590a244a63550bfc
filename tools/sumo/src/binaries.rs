//! Where SUMO's programs are, and the two runs of them that are not a simulation: `--version` and
//! the OpenDRIVE → SUMO network conversion.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::SumoError;

/// The directory variable that overrides where SUMO's programs are looked for.
pub const SUMO_BIN_VAR: &str = "V2T_SUMO_BIN";

/// The paths of SUMO's `sumo` and `netconvert`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SumoBinaries {
    /// The simulator.
    pub sumo: PathBuf,
    /// The network converter.
    pub netconvert: PathBuf,
}

impl SumoBinaries {
    /// Finds SUMO: in the directory `$V2T_SUMO_BIN`, then in
    /// `<workspace>/target/sumo-venv/lib/python3*/site-packages/sumo/bin` (the workspace found by
    /// walking up from the current directory and from the running executable to a `Cargo.toml`
    /// with a `[workspace]` table), then on `PATH`.
    pub fn find() -> Result<Self, SumoError> {
        let mut searched = Vec::new();
        let mut dirs = Vec::new();
        if let Some(dir) = std::env::var_os(SUMO_BIN_VAR) {
            dirs.push(PathBuf::from(dir));
        }
        for root in workspace_roots() {
            dirs.extend(venv_bin_dirs(&root));
        }
        for dir in dirs {
            if let Some(found) = Self::in_dir(&dir) {
                return Ok(found);
            }
            searched.push(dir.display().to_string());
        }
        let path = std::env::var_os("PATH").unwrap_or_default();
        let on_path = |name: &str| std::env::split_paths(&path).map(|d| d.join(name)).find(|p| is_executable(p));
        if let (Some(sumo), Some(netconvert)) = (on_path("sumo"), on_path("netconvert")) {
            return Ok(Self { sumo, netconvert });
        }
        searched.push("PATH".to_owned());
        Err(SumoError::MissingBinaries { searched: searched.join(", ") })
    }

    /// `sumo` and `netconvert` in `dir`, if both are there.
    pub fn in_dir(dir: &Path) -> Option<Self> {
        let (sumo, netconvert) = (dir.join("sumo"), dir.join("netconvert"));
        (is_executable(&sumo) && is_executable(&netconvert)).then_some(Self { sumo, netconvert })
    }

    /// The first line of `sumo --version`, e.g. `Eclipse SUMO sumo 1.28.0`.
    pub fn version(&self) -> Result<String, SumoError> {
        let mut cmd = self.command(&self.sumo);
        cmd.arg("--version");
        let out = run(&mut cmd)?;
        let text = String::from_utf8_lossy(&out.stdout);
        Ok(text.lines().next().unwrap_or_default().trim().to_owned())
    }

    /// A command running `program` with SUMO's environment: `SUMO_HOME` set to the installation
    /// the binaries came from (where it has a `data` directory and `SUMO_HOME` is unset), so SUMO
    /// finds its schemas and type maps.
    pub(crate) fn command(&self, program: &Path) -> Command {
        let mut cmd = Command::new(program);
        let home = program.parent().and_then(Path::parent).filter(|h| h.join("data").is_dir());
        if let (Some(home), None) = (home, std::env::var_os("SUMO_HOME")) {
            cmd.env("SUMO_HOME", home);
        }
        cmd
    }
}

/// Converts the OpenDRIVE map `xodr` into the SUMO network `out` with `netconvert`:
/// coordinates kept as in the map (no offset), OpenDRIVE ids kept as `origId` lane parameters,
/// junction lanes shaped by the map's connecting roads, no U-turns.
///
/// `--junctions.limit-turn-speed 5.5` (also netconvert 1.28's default, pinned here) caps the
/// speed of a junction lane at an average lateral acceleration of 5.5 m/s² over its curve (angles
/// under 15° are not limited): on the proving ground this lowers right turns to about 12 m/s and
/// left turns barely, a sensible ceiling for a driver model; the map's own turn speeds (30 km/h
/// in `<road><type><speed>`) are not read by netconvert's OpenDRIVE import.
///
/// netconvert's warnings appear only in the error when the conversion fails.
pub fn convert_map(bins: &SumoBinaries, xodr: &Path, out: &Path) -> Result<(), SumoError> {
    let mut cmd = bins.command(&bins.netconvert);
    cmd.arg("--opendrive-files")
        .arg(xodr)
        .arg("-o")
        .arg(out)
        .args(["--offset.disable-normalization", "--output.original-names"])
        .args(["--opendrive.internal-shapes", "--no-turnarounds"])
        .args(["--junctions.limit-turn-speed", "5.5"]);
    run(&mut cmd).map(|_| ())
}

/// Runs `cmd` to its end; a failure to start or a non-zero exit is an error with its output.
fn run(cmd: &mut Command) -> Result<Output, SumoError> {
    let line = command_line(cmd);
    let out = cmd.output().map_err(|source| SumoError::Spawn { command: line.clone(), source })?;
    if out.status.success() {
        return Ok(out);
    }
    let mut text = String::from_utf8_lossy(&out.stdout).into_owned();
    text.push_str(&String::from_utf8_lossy(&out.stderr));
    Err(SumoError::ToolFailed { command: line, status: out.status.to_string(), output_tail: tail(&text, 40) })
}

/// `cmd` as a shell-like line, for messages.
pub(crate) fn command_line(cmd: &Command) -> String {
    std::iter::once(cmd.get_program())
        .chain(cmd.get_args())
        .map(|a| a.to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join(" ")
}

/// The last `lines` lines of `text`.
pub(crate) fn tail(text: &str, lines: usize) -> String {
    let all: Vec<&str> = text.trim_end().lines().collect();
    all.get(all.len().saturating_sub(lines)..).unwrap_or_default().join("\n")
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt as _;
    p.metadata().is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

/// Workspace roots above the current directory and above the running executable.
fn workspace_roots() -> Vec<PathBuf> {
    let starts = [std::env::current_dir().ok(), std::env::current_exe().ok()];
    let mut roots: Vec<PathBuf> = Vec::new();
    for start in starts.into_iter().flatten() {
        let root = start.ancestors().find(|dir| {
            std::fs::read_to_string(dir.join("Cargo.toml")).is_ok_and(|t| t.lines().any(|l| l.trim() == "[workspace]"))
        });
        if let Some(root) = root
            && !roots.iter().any(|r| r == root)
        {
            roots.push(root.to_path_buf());
        }
    }
    roots
}

/// `<root>/target/sumo-venv/lib/python3*/site-packages/sumo/bin`, newest Python first.
fn venv_bin_dirs(root: &Path) -> Vec<PathBuf> {
    let lib = root.join("target/sumo-venv/lib");
    let mut pythons: Vec<PathBuf> = std::fs::read_dir(&lib)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with("python3"))
        .map(|e| e.path().join("site-packages/sumo/bin"))
        .collect();
    pythons.sort();
    pythons.reverse();
    if pythons.is_empty() {
        pythons.push(lib.join("python3*/site-packages/sumo/bin"));
    }
    pythons
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn tails_keep_the_last_lines() {
        assert_eq!(tail("a\nb\nc\n", 2), "b\nc");
        assert_eq!(tail("a", 5), "a");
        assert_eq!(tail("", 5), "");
    }

    #[test]
    fn a_directory_without_sumo_holds_no_binaries() {
        let dir = tempfile::tempdir().unwrap();
        assert!(SumoBinaries::in_dir(dir.path()).is_none());
    }

    #[test]
    fn the_missing_binaries_error_says_how_to_install() {
        let err = SumoError::MissingBinaries { searched: "PATH".to_owned() };
        let text = err.to_string();
        assert!(text.contains("scripts/install-sumo"), "{text}");
        assert!(text.contains("pip install eclipse-sumo==1.28.0"), "{text}");
        assert!(text.contains("V2T_SUMO_BIN"), "{text}");
    }
}
