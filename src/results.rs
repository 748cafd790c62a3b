//! `--markdown FILE`: the measured tables of `docs/results.md`, each written by the command
//! that measures it. A command owns one section of the file, between its markers, and
//! replaces only that section, so `gema2 evaluate` and `gema2 bench` write one page together
//! and neither is ever edited by hand.

use anyhow::{Context, Result};
use std::path::Path;

/// What a new results page starts with.
const PAGE_HEADER: &str = "# Measured results\n\nEvery table on this page is written by the command named \
above it (`--markdown docs/results.md`), with the machine and date it ran on. Regenerate a table \
with its command; never edit this page by hand. What the figures mean: [how-it-works.md](how-it-works.md).\n";

/// Replaces section `name` of the markdown file at `path` with `body` (creating the file, or
/// appending the section, when it has none), stamped with `command`, the date and the machine.
pub fn write_section(path: &Path, name: &str, command: &str, body: &str) -> Result<()> {
    let old = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => PAGE_HEADER.to_owned(),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    let section = format!(
        "<!-- BEGIN {name} -->\n`{command}`, {} on {}.\n\n{}\n<!-- END {name} -->",
        today(),
        machine(),
        body.trim_end()
    );
    let text = replace_section(&old, name, &section);
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// `text` with its section `name` (markers included) replaced by `section`, or with `section`
/// appended when it has none.
fn replace_section(text: &str, name: &str, section: &str) -> String {
    let (begin, end) = (format!("<!-- BEGIN {name} -->"), format!("<!-- END {name} -->"));
    match (text.find(&begin), text.find(&end)) {
        (Some(b), Some(e)) if e > b => format!("{}{section}{}", &text[..b], &text[e + end.len()..]),
        _ => format!("{}\n{section}\n", text.trim_end()),
    }
}

/// Today's date, UTC, as YYYY-MM-DD.
fn today() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
    let (y, m, d) = civil_from_days((secs / 86_400) as i64);
    format!("{y:04}-{m:02}-{d:02}")
}

/// The date `days` after 1970-01-01 (Howard Hinnant's `civil_from_days`).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// The processor and how many cores this process may use, as far as the system says.
fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find_map(|l| l.strip_prefix("model name").map(|v| v.trim_start_matches([' ', '\t', ':']).to_owned()))
        })
        .unwrap_or_else(|| "an unknown processor".to_owned());
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    format!("{cpu}, {cores} cores, gema2 {}", env!("CARGO_PKG_VERSION"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_section_replaces_its_own_and_leaves_the_others() {
        let page = "# t\n\n<!-- BEGIN a -->\nold a\n<!-- END a -->\n\n<!-- BEGIN b -->\nold b\n<!-- END b -->\n";
        let new = replace_section(page, "a", "<!-- BEGIN a -->\nnew a\n<!-- END a -->");
        assert!(new.contains("new a") && !new.contains("old a") && new.contains("old b"), "{new}");
        let appended = replace_section(&new, "c", "<!-- BEGIN c -->\nc\n<!-- END c -->");
        assert!(appended.ends_with("<!-- BEGIN c -->\nc\n<!-- END c -->\n") && appended.contains("old b"));
    }

    #[test]
    fn days_count_from_1970() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(19_723), (2024, 1, 1));
        assert_eq!(civil_from_days(20_783), (2026, 11, 26));
    }
}
