//! `gema2 settings`: every key `--set` takes, one a line, with its stage, default, range and
//! meaning, read from the tables `--set` itself applies (`localize::settings`).

use anyhow::Result;
use clap::Args;
use localize::Gema2Config;

#[derive(Args, Debug)]
pub struct SettingsArgs {
    /// Only the keys that contain this text (in the key or its meaning).
    pub filter: Option<String>,
}

/// The table, one key a line, grouped by stage.
pub fn render(config: &Gema2Config, filter: Option<&str>) -> String {
    let rows: Vec<_> = config
        .rows()
        .into_iter()
        .filter(|r| filter.is_none_or(|f| r.key.contains(f) || r.meaning.contains(f)))
        .collect();
    let width = |f: &dyn Fn(&localize::settings::SettingRow) -> usize| rows.iter().map(f).max().unwrap_or(0);
    let (kw, dw, rw) = (width(&|r| r.key.len()), width(&|r| r.default.len()).max(7), width(&|r| r.range.len()));
    let mut out = String::new();
    let mut stage = "";
    for r in &rows {
        if r.stage != stage {
            stage = r.stage;
            out.push_str(&format!("\n{stage}:\n  {:kw$}  {:dw$}  {:rw$}  meaning\n", "key", "default", "range"));
        }
        out.push_str(&format!("  {:kw$}  {:dw$}  {:rw$}  {}\n", r.key, r.default, r.range, r.meaning));
    }
    if rows.is_empty() {
        out.push_str("no setting matches\n");
    }
    out.push_str(
        "\nSet with `--set KEY=VALUE` on `gema2 locate`, `evaluate`, `lines` and the stages (a pipeline \
         file's `args`).\nAngles are in degrees. A key of `segment, localize` must be given to both stages.\n",
    );
    out
}

pub fn run(a: SettingsArgs) -> Result<()> {
    print!("{}", render(&Gema2Config::default(), a.filter.as_deref()));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_key_is_listed_once_with_its_default() {
        let text = render(&Gema2Config::default(), None);
        for key in Gema2Config::keys() {
            let lines = text.lines().filter(|l| l.split_whitespace().next() == Some(key)).count();
            assert_eq!(lines, 1, "{key} in:\n{text}");
        }
        assert!(text.contains("\nsegment:\n") && text.contains("\nlocalize:\n"), "{text}");
        let merge = text.lines().find(|l| l.trim_start().starts_with("merge_angle ")).unwrap();
        assert!(merge.contains("0 to 90 degrees"), "{merge}");
        assert!(render(&Gema2Config::default(), Some("slide_")).lines().all(|l| !l.contains("merge_angle")));
    }
}
