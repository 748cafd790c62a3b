//! Helpers shared by the integration tests that start real pipelines.

use std::path::{Path, PathBuf};

/// Says, past the harness's capture, that a test could not run its checks here: libtest has no
/// "skipped", and a test that returns early would otherwise read as passed. `.ci/run` lists
/// these lines at the end of its log.
#[allow(dead_code)] // not every test file skips
pub fn skipped(test: &str, why: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "SKIPPED {test}: {why}");
}

/// Writes `dir/name`: the four-stage pipeline (mapserver serving `map`, localize, segment with
/// the paper's line visibility, acquire with `acquire_args`, never restarted so a finished log
/// ends the run) and returns its path.
#[allow(dead_code)] // tests/cli.rs starts no pipeline
pub fn write_pipeline(dir: &Path, name: &str, map: &str, acquire_args: &[&str]) -> PathBuf {
    let args = acquire_args.iter().map(|a| format!("{a:?}")).collect::<Vec<_>>().join(", ");
    let text = format!(
        "[[stage]]\nname = \"mapserver\"\nkind = \"mapserver\"\nargs = [\"--map\", {map:?}]\n\n\
         [[stage]]\nname = \"localize\"\nkind = \"localize\"\n\n\
         [[stage]]\nname = \"segment\"\nkind = \"segment\"\nimplementation = \"line-visibility\"\n\n\
         [[stage]]\nname = \"acquire\"\nkind = \"acquire\"\nargs = [{args}]\nrestart = \"never\"\n"
    );
    let path = dir.join(name);
    std::fs::write(&path, text).expect("the pipeline file is written");
    path
}

/// The pipeline file `text` with `lines` (TOML, one setting a line) added to its stage of kind
/// `kind`, after that stage's `kind = ...` line. A file with no such stage fails the test.
#[allow(dead_code)] // not every test file edits a pipeline
pub fn with_stage_lines(text: &str, kind: &str, lines: &str) -> String {
    let at = format!("kind = \"{kind}\"\n");
    let edited = text.replace(&at, &format!("{at}{lines}\n"));
    assert_ne!(edited, text, "no stage of kind {kind} in:\n{text}");
    edited
}

/// The project's Python, with scripts/requirements.txt installed (made on first use by
/// scripts/python-env in target/).
#[allow(dead_code)] // only the interop tests run Python
pub fn python() -> PathBuf {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/python-env");
    let out = std::process::Command::new(script).output().expect("scripts/python-env runs");
    assert!(out.status.success(), "scripts/python-env: {}", String::from_utf8_lossy(&out.stderr));
    PathBuf::from(String::from_utf8_lossy(&out.stdout).trim())
}
