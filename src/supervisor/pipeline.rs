//! The declarative pipeline file (TOML): which stages run, how, where, and what happens when
//! one dies.

use anyhow::{bail, Context, Result};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The pipeline `gema2 run` uses when given no file.
pub const DEFAULT_PIPELINE: &str = include_str!("../../pipelines/default.toml");

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Restart {
    Always,
    OnFailure,
    Never,
}

impl Restart {
    /// As the pipeline file writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            Restart::Always => "always",
            Restart::OnFailure => "on-failure",
            Restart::Never => "never",
        }
    }
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    Acquire,
    Segment,
    Localize,
    Mapserver,
    /// The recorder (`viewer` binary): every message to a rerun recording.
    Viewer,
    /// The ROS 2 bridge: scans in from DDS (a source, as `acquire` is), poses out.
    Ros2,
}

impl Kind {
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Acquire => "acquire",
            Kind::Segment => "segment",
            Kind::Localize => "localize",
            Kind::Mapserver => "mapserver",
            Kind::Viewer => "viewer",
            Kind::Ros2 => "ros2",
        }
    }

    /// When a stage of this kind starts, earliest first: each stage is started once what it
    /// waits for runs (the localizer is ready only with a map) and before what feeds it (so no
    /// message is published before its consumer listens), whatever the file's order. The
    /// recorder listens to every topic, the map among them, so it comes first.
    pub fn start_rank(self) -> u8 {
        match self {
            Kind::Viewer => 0,
            Kind::Mapserver => 1,
            Kind::Localize => 2,
            Kind::Segment => 3,
            Kind::Acquire | Kind::Ros2 => 4,
        }
    }

    /// Whether stages of this kind publish scans: the pipeline's sources.
    pub fn is_source(self) -> bool {
        matches!(self, Kind::Acquire | Kind::Ros2)
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    pub name: String,
    pub kind: Kind,
    /// A program to run instead of `gema2 stage <kind>`.
    pub binary: Option<PathBuf>,
    pub implementation: Option<String>,
    #[serde(default)]
    pub args: Vec<String>,
    pub cpu: Option<usize>,
    /// SCHED_FIFO priority (1-99): see `messages::placement`.
    pub priority: Option<u8>,
    #[serde(default = "on_failure")]
    pub restart: Restart,
    /// What the stage can be swapped to by name (`gema2 swap STAGE --to NAME`), each a
    /// `[[stage.alternative]]` table.
    #[serde(default, rename = "alternative")]
    pub alternatives: Vec<Alternative>,
}

/// A named replacement for a stage: another implementation, program or arguments.
#[derive(Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Alternative {
    pub name: String,
    pub implementation: Option<String>,
    pub binary: Option<PathBuf>,
    /// Instead of the stage's arguments, when given.
    pub args: Option<Vec<String>>,
}

fn on_failure() -> Restart {
    Restart::OnFailure
}

/// How the supervisor itself runs: it is the consumer of the poses, so its wake-up is the last
/// hop's; and it holds the machine-wide wake-up latency request for the run.
#[derive(Clone, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct SupervisorSpec {
    /// Core to pin the supervisor to (stages without a `cpu` keep the cores it started with).
    pub cpu: Option<usize>,
    /// SCHED_FIFO priority (1-99); not inherited by the stages.
    pub priority: Option<u8>,
    /// Hold a PM QoS request bounding idle cores' wake-up latency to this many microseconds
    /// while the pipeline runs (0: idle cores poll instead of sleeping); needs root.
    pub wake_latency_us: Option<u32>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    #[serde(default)]
    pub supervisor: SupervisorSpec,
    /// `KEY=VALUE` settings for the whole pipeline (`gema2 settings` lists the keys): each goes
    /// to every stage that takes it, so the segment and localize stages cannot disagree on a key
    /// both take (the error model, `wall_ends`). Given after a stage's own `args`.
    #[serde(default)]
    pub settings: Vec<String>,
    #[serde(rename = "stage")]
    pub stages: Vec<StageSpec>,
}

/// How errors name the embedded default pipeline.
pub const EMBEDDED: &str = "<embedded default pipeline>";

impl Pipeline {
    pub fn parse(text: &str, origin: &Path) -> Result<Self> {
        Self::parse_with(text, origin, &|name| std::env::var(name).ok())
    }

    /// [`parse`](Self::parse), with `${NAME}` and `${NAME:-default}` in a stage's `args` and
    /// `binary` read from `env` (the environment), so one file serves every log or port:
    /// `GEMA2_LOG=run.log gema2 run --pipeline pipelines/replay.toml`.
    pub fn parse_with(text: &str, origin: &Path, env: &dyn Fn(&str) -> Option<String>) -> Result<Self> {
        let mut p: Pipeline = toml::from_str(text).with_context(|| format!("{}: not a pipeline", origin.display()))?;
        p.share_settings().with_context(|| format!("{}: settings", origin.display()))?;
        for s in &mut p.stages {
            let at = |e: String| anyhow::anyhow!("{}: stage {:?}: {e}", origin.display(), s.name);
            for a in &mut s.args {
                *a = expand(a, env).map_err(at)?;
            }
            if let Some(b) = &s.binary {
                let expanded = expand(&b.to_string_lossy(), env).map_err(at)?;
                s.binary = Some(PathBuf::from(expanded));
            }
        }
        let priorities = messages::placement::REALTIME_PRIORITIES;
        for (k, s) in p.stages.iter().enumerate() {
            if p.stages[..k].iter().any(|o| o.name == s.name) {
                bail!("{}: two stages are called {:?}", origin.display(), s.name);
            }
            if let Some(q) = s.priority.filter(|q| !priorities.contains(q)) {
                bail!("{}: stage {:?}: priority {q} is not in 1..=99", origin.display(), s.name);
            }
        }
        if let Some(q) = p.supervisor.priority.filter(|q| !priorities.contains(q)) {
            bail!("{}: [supervisor] priority {q} is not in 1..=99", origin.display());
        }
        if !p.stages.iter().any(|s| s.kind.is_source()) {
            bail!("{}: no acquire or ros2 stage: nothing would produce scans", origin.display());
        }
        Ok(p)
    }

    /// Checks the pipeline's `settings` and appends each, as `--set`, to the stages that take
    /// it: a segmentation key to the segment stages, a map-corner key to the map server (which
    /// builds the model with it), every key to the localize stages.
    fn share_settings(&mut self) -> Result<()> {
        if self.settings.is_empty() {
            return Ok(());
        }
        localize::Gema2Config::default().apply(&self.settings)?;
        for s in &mut self.stages {
            for kv in &self.settings {
                let key = kv.split_once('=').map_or(kv.as_str(), |(k, _)| k.trim());
                let takes = match s.kind {
                    Kind::Segment => segment::SegmenterConfig::SETTINGS.iter().any(|spec| spec.key == key),
                    Kind::Localize => true,
                    // the model's corner settings: the map server builds it with them
                    Kind::Mapserver => localize::Gema2Config::MAP_SETTINGS.iter().any(|spec| spec.key == key),
                    _ => false,
                };
                if takes {
                    s.args.extend(["--set".to_owned(), kv.clone()]);
                }
            }
        }
        Ok(())
    }

    /// Refuses a `cpu` (a stage's or the supervisor's) that is not among `allowed`, the cores
    /// the kernel lets the supervisor pin to ([`messages::placement::allowed_cores`]): a
    /// pipeline written for a larger machine would otherwise restart its pinned stages for
    /// ever.
    pub fn check_cores(&self, origin: &Path, allowed: &[usize]) -> Result<()> {
        let pinned = self.stages.iter().map(|s| (format!("stage {:?}", s.name), s.cpu));
        for (who, cpu) in pinned.chain([("[supervisor]".to_owned(), self.supervisor.cpu)]) {
            if let Some(c) = cpu.filter(|c| !allowed.contains(c)) {
                bail!(
                    "{}: {who}: cpu {c} is not one this machine lets the pipeline use (cores {})",
                    origin.display(),
                    messages::placement::ranges(allowed)
                );
            }
        }
        Ok(())
    }

    pub fn load(path: Option<&Path>) -> Result<Self> {
        match path {
            Some(p) => Self::parse(&std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?, p),
            None => Self::parse(DEFAULT_PIPELINE, Path::new(EMBEDDED)),
        }
    }
}

/// `text` with each `${NAME}` replaced by `env(NAME)`, and each `${NAME:-default}` by it or,
/// when it is unset or empty, by `default`; an unset `${NAME}` is an error that names it.
pub fn expand(text: &str, env: &dyn Fn(&str) -> Option<String>) -> Result<String, String> {
    let mut out = String::new();
    let mut rest = text;
    while let Some(start) = rest.find("${") {
        out.push_str(&rest[..start]);
        let after = &rest[start + 2..];
        let end = after.find('}').ok_or_else(|| format!("{text:?}: a ${{ without its closing }}"))?;
        let (name, default) = match after[..end].split_once(":-") {
            Some((n, d)) => (n, Some(d)),
            None => (&after[..end], None),
        };
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(format!("{text:?}: ${{{name}}} is not a variable name"));
        }
        match (env(name).filter(|v| !v.is_empty()), default) {
            (Some(v), _) => out.push_str(&v),
            (None, Some(d)) => out.push_str(d),
            (None, None) => return Err(format!("{text:?} needs the environment variable {name}, which is not set")),
        }
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

/// Replaces (or adds) `--flag value` in an argument list.
pub fn set_arg(args: &mut Vec<String>, flag: &str, value: &str) {
    if let Some(k) = args.iter().position(|a| a == flag) {
        if k + 1 < args.len() {
            args[k + 1] = value.to_owned();
            return;
        }
        args.truncate(k);
    }
    args.push(flag.to_owned());
    args.push(value.to_owned());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variables_in_a_pipeline_s_args_come_from_the_environment() {
        let env = |name: &str| match name {
            "LOG" => Some("/data/run.log".to_owned()),
            "EMPTY" => Some(String::new()),
            _ => None,
        };
        assert_eq!(expand("${LOG}", &env).unwrap(), "/data/run.log");
        assert_eq!(expand("at ${RATE:-10} Hz, ${EMPTY:-x}", &env).unwrap(), "at 10 Hz, x");
        assert_eq!(expand("plain", &env).unwrap(), "plain");
        assert!(expand("${NOPE}", &env).unwrap_err().contains("environment variable NOPE"));
        assert!(expand("${LOG", &env).unwrap_err().contains("closing"));
        assert!(expand("${A B}", &env).unwrap_err().contains("not a variable name"));
        let text =
            "[[stage]]\nname = \"a\"\nkind = \"acquire\"\nargs = [\"--log\", \"${LOG}\", \"--x\", \"${NOPE}\"]\n";
        let err = Pipeline::parse_with(text, Path::new("p.toml"), &env).unwrap_err();
        assert!(format!("{err:#}").contains("p.toml: stage \"a\": \"${NOPE}\" needs the environment variable NOPE"));
        let ok = text.replace("${NOPE}", "${NOPE:-1}");
        let p = Pipeline::parse_with(&ok, Path::new("p.toml"), &env).unwrap();
        assert_eq!(p.stages[0].args, ["--log", "/data/run.log", "--x", "1"]);
    }

    /// One list of settings reaches every stage that takes each key, after the stage's own
    /// arguments; a bad key is refused naming the file.
    #[test]
    fn the_pipeline_s_settings_go_to_every_stage_that_takes_them() {
        let text = "settings = [\"error_constant=0.05\", \"screened=100\", \"map_reach=3\", \"odom_alpha1=0.2\"]\n\
                    [[stage]]\nname = \"s\"\nkind = \"segment\"\nargs = [\"--impl\", \"x\"]\n\
                    [[stage]]\nname = \"l\"\nkind = \"localize\"\n\
                    [[stage]]\nname = \"a\"\nkind = \"acquire\"\n\
                    [[stage]]\nname = \"m\"\nkind = \"mapserver\"\n";
        let p = Pipeline::parse(text, Path::new("p.toml")).unwrap();
        assert_eq!(p.stages[0].args, ["--impl", "x", "--set", "error_constant=0.05"]);
        let localize = ["error_constant=0.05", "screened=100", "map_reach=3", "odom_alpha1=0.2"];
        assert_eq!(p.stages[1].args, localize.iter().flat_map(|kv| ["--set", kv]).collect::<Vec<_>>());
        assert!(p.stages[2].args.is_empty());
        // the model is built with the localizer's corner settings
        assert_eq!(p.stages[3].args, ["--set", "map_reach=3"]);
        let err = Pipeline::parse(&text.replace("screened=100", "screend=1"), Path::new("p.toml")).unwrap_err();
        assert!(format!("{err:#}").contains("p.toml: settings") && format!("{err:#}").contains("screend"), "{err:#}");
    }

    /// The shipped example pipelines parse, given the variables their comments name.
    #[test]
    fn the_example_pipelines_parse() {
        let env = |name: &str| Some(format!("/x/{name}"));
        for file in ["replay.toml", "urg-serial.toml", "low-latency.toml", "default.toml"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines").join(file);
            let text = std::fs::read_to_string(&path).unwrap();
            Pipeline::parse_with(&text, &path, &env).unwrap_or_else(|e| panic!("{file}: {e:#}"));
        }
    }

    #[test]
    fn the_default_pipeline_parses_and_bad_ones_are_explained() {
        let p = Pipeline::load(None).unwrap();
        assert_eq!(
            p.stages.iter().map(|s| s.kind).collect::<Vec<_>>(),
            vec![Kind::Mapserver, Kind::Localize, Kind::Segment, Kind::Acquire]
        );
        let low = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/low-latency.toml"));
        let p = Pipeline::load(Some(low)).unwrap();
        assert_eq!(p.supervisor, SupervisorSpec { cpu: Some(1), priority: Some(40), wake_latency_us: Some(0) });
        assert!(p.stages.iter().filter(|s| s.kind != Kind::Mapserver).all(|s| s.priority.is_some()));
        let err = Pipeline::parse("[[stage]]\nname = \"a\"\nkind = \"segment\"\n", Path::new("p.toml")).unwrap_err();
        assert!(format!("{err:#}").contains("no acquire or ros2 stage"));
        let with = "[[stage]]\nname = \"s\"\nkind = \"segment\"\n[[stage.alternative]]\nname = \"sm\"\n\
                    implementation = \"split-and-merge\"\n[[stage]]\nname = \"a\"\nkind = \"acquire\"\n";
        let p = Pipeline::parse(with, Path::new("p.toml")).unwrap();
        assert_eq!(p.stages[0].alternatives[0].implementation.as_deref(), Some("split-and-merge"));
        let err = Pipeline::parse("[[stage]]\nname = \"a\"\nkind = \"laser\"\n", Path::new("p.toml")).unwrap_err();
        assert!(format!("{err:#}").contains("p.toml"));
        let err = Pipeline::parse("[[stage]]\nname = \"a\"\nkind = \"acquire\"\npriority = 0\n", Path::new("p.toml"))
            .unwrap_err();
        assert!(format!("{err:#}").contains("p.toml: stage \"a\": priority 0"), "{err:#}");
        let err = Pipeline::parse(
            "[supervisor]\npriority = 100\n[[stage]]\nname = \"a\"\nkind = \"acquire\"\n",
            Path::new("p.toml"),
        )
        .unwrap_err();
        assert!(format!("{err:#}").contains("[supervisor] priority 100"), "{err:#}");
        let p = Pipeline::parse(
            "[supervisor]\ncpu = 1\n[[stage]]\nname = \"a\"\nkind = \"acquire\"\ncpu = 3\n",
            Path::new("p.toml"),
        )
        .unwrap();
        assert!(p.check_cores(Path::new("p.toml"), &[0, 1, 2, 3]).is_ok());
        let err = p.check_cores(Path::new("p.toml"), &[0, 1]).unwrap_err();
        assert_eq!(
            format!("{err:#}"),
            "p.toml: stage \"a\": cpu 3 is not one this machine lets the pipeline use (cores 0-1)"
        );
        let err = p.check_cores(Path::new("p.toml"), &[2, 3]).unwrap_err();
        assert!(format!("{err:#}").starts_with("p.toml: [supervisor]: cpu 1 "), "{err:#}");
        let mut args = vec!["--rate".to_owned(), "10".to_owned()];
        set_arg(&mut args, "--rate", "max");
        set_arg(&mut args, "--scans", "5");
        assert_eq!(args, ["--rate", "max", "--scans", "5"]);
    }
}
