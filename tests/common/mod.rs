//! Helpers shared by the integration tests that start real pipelines.

use std::path::{Path, PathBuf};

/// Writes `dir/name`: the four-stage pipeline (mapserver serving `map`, localize, segment with
/// the paper's line visibility, acquire with `acquire_args`, never restarted so a finished log
/// ends the run) and returns its path.
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
