//! Parameters set by name, as `--set KEY=VALUE` on a command line: `gema2 locate` and the
//! pipeline's `segment` and `localize` stages take the same words, so a setting measured
//! offline can be deployed unchanged. This module parses a setting and applies the
//! segmentation's; `localize` applies the rest (`localize::Gema2Config::set`).

use crate::SegmenterConfig;
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum SettingError {
    #[error("setting {0:?}: expected KEY=VALUE")]
    NotKeyValue(String),
    #[error("setting {key}: {value:?} is not a finite number")]
    NotANumber { key: String, value: String },
    #[error("setting {key}: {value} is not a whole number of at least 0")]
    NotACount { key: String, value: f64 },
    #[error("setting {key}: {value} is out of range: it must be {range}")]
    OutOfRange { key: String, value: f64, range: &'static str },
    #[error("unknown setting {key:?}{}; `gema2 settings` lists every key with its default and range",
            suggestion.map(|s| format!(" (did you mean {s:?}?)")).unwrap_or_default())]
    Unknown { key: String, suggestion: Option<&'static str> },
}

impl SettingError {
    /// `key` is no setting among `known`: the error, with the nearest known key when one is
    /// close enough to be a typo.
    pub fn unknown(key: &str, known: impl IntoIterator<Item = &'static str>) -> Self {
        let suggestion = known
            .into_iter()
            .map(|k| (edit_distance(key, k), k))
            .filter(|&(d, k)| d <= 2.max(k.len() / 4))
            .min_by_key(|&(d, _)| d)
            .map(|(_, k)| k);
        SettingError::Unknown { key: key.to_string(), suggestion }
    }
}

/// Levenshtein distance between `a` and `b`, in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (diagonal + usize::from(ca != cb)).min(above + 1).min(row[j] + 1);
            diagonal = above;
        }
    }
    row[b.len()]
}

/// What values a setting takes: how `--set` checks a value and how `gema2 settings` shows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// A whole number, at least 0.
    Count,
    /// A whole number, at least 1.
    Step,
    /// Degrees from 0 to 90, kept in radians.
    Degrees,
    /// At least 0.
    NonNegative,
    /// Above 0.
    Positive,
    /// From 0 to 1.
    Fraction,
    /// 0 (off) or anything else (on).
    Switch,
    /// From `lo` to `hi`, described by the text.
    Within(f64, f64, &'static str),
}

impl Range {
    /// The range in words.
    pub fn describe(&self) -> &'static str {
        match self {
            Range::Count => "a whole number >= 0",
            Range::Step => "a whole number >= 1",
            Range::Degrees => "0 to 90 degrees",
            Range::NonNegative => ">= 0",
            Range::Positive => "> 0",
            Range::Fraction => "a fraction, 0 to 1",
            Range::Switch => "0 (off) or 1 (on)",
            Range::Within(_, _, text) => text,
        }
    }

    /// The value of `s` in the units the parameter keeps (degrees become radians, a switch 0
    /// or 1), or why it is out of range.
    pub fn check(&self, s: &Setting<'_>) -> Result<f64, SettingError> {
        Ok(match self {
            Range::Count => s.count()? as f64,
            Range::Step => s.step()? as f64,
            Range::Degrees => s.degrees()?,
            Range::NonNegative => s.non_negative()?,
            Range::Positive => s.positive()?,
            Range::Fraction => s.fraction()?,
            Range::Switch => f64::from(u8::from(s.switch())),
            Range::Within(lo, hi, text) => s.within(*lo, *hi, text)?,
        })
    }

    /// A kept value as a user writes it (radians back to degrees).
    pub fn show(&self, kept: f64) -> String {
        let v = if *self == Range::Degrees { kept.to_degrees() } else { kept };
        let rounded = (v * 1e6).round() / 1e6;
        format!("{rounded}")
    }
}

/// A parameter's value as a number a setting carries, whatever the field's type.
pub trait SettingValue: Copy {
    fn to_setting(self) -> f64;
    fn from_setting(v: f64) -> Self;
}

impl SettingValue for f64 {
    fn to_setting(self) -> f64 {
        self
    }
    fn from_setting(v: f64) -> Self {
        v
    }
}

impl SettingValue for usize {
    fn to_setting(self) -> f64 {
        self as f64
    }
    fn from_setting(v: f64) -> Self {
        v as usize
    }
}

impl SettingValue for u32 {
    fn to_setting(self) -> f64 {
        f64::from(self)
    }
    fn from_setting(v: f64) -> Self {
        v as u32
    }
}

impl SettingValue for bool {
    fn to_setting(self) -> f64 {
        f64::from(u8::from(self))
    }
    fn from_setting(v: f64) -> Self {
        v != 0.0
    }
}

/// One parameter of a configuration `C` settable by name: its key, range and meaning, and how
/// to read and write it. A configuration's table of these is the only list of its keys, so
/// what `--set` accepts and what `gema2 settings` lists cannot drift apart.
pub struct SettingSpec<C> {
    pub key: &'static str,
    pub range: Range,
    pub meaning: &'static str,
    /// The value, in the units the parameter keeps.
    pub get: fn(&C) -> f64,
    /// Writes a value already checked by `range`.
    pub put: fn(&mut C, f64),
}

impl<C> SettingSpec<C> {
    /// The value `config` holds, as a user writes it.
    pub fn shown(&self, config: &C) -> String {
        self.range.show((self.get)(config))
    }
}

/// Applies `s` through `table` when it names one of its keys: `Ok(true)`; `Ok(false)` when
/// it names none.
pub fn set_by_table<C>(table: &[SettingSpec<C>], config: &mut C, s: &Setting<'_>) -> Result<bool, SettingError> {
    match table.iter().find(|spec| spec.key == s.key) {
        Some(spec) => {
            (spec.put)(config, spec.range.check(s)?);
            Ok(true)
        }
        None => Ok(false),
    }
}

/// A [`SettingSpec`] of the field at `$($field).+` of a `$config`.
#[macro_export]
macro_rules! setting {
    ($config:ty, $key:literal, $range:expr, $meaning:literal, $($field:ident).+) => {
        $crate::settings::SettingSpec::<$config> {
            key: $key,
            range: $range,
            meaning: $meaning,
            get: |c: &$config| $crate::settings::SettingValue::to_setting(c.$($field).+),
            put: |c: &mut $config, v| c.$($field).+ = $crate::settings::SettingValue::from_setting(v),
        }
    };
}

/// One `KEY=VALUE`, the value a finite number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting<'a> {
    pub key: &'a str,
    pub value: f64,
}

impl<'a> Setting<'a> {
    pub fn parse(kv: &'a str) -> Result<Self, SettingError> {
        let (key, value) = kv.split_once('=').ok_or_else(|| SettingError::NotKeyValue(kv.to_string()))?;
        let key = key.trim();
        let not_a_number = || SettingError::NotANumber { key: key.to_string(), value: value.to_string() };
        let value: f64 = value.trim().parse().map_err(|_| not_a_number())?;
        if !value.is_finite() {
            return Err(not_a_number());
        }
        Ok(Setting { key, value })
    }

    /// The value as a count: a whole number, at least 0.
    pub fn count(&self) -> Result<usize, SettingError> {
        if self.value < 0.0 || self.value.fract() != 0.0 || self.value > u32::MAX as f64 {
            return Err(SettingError::NotACount { key: self.key.to_string(), value: self.value });
        }
        Ok(self.value as usize)
    }

    /// The value as a count of at least 1 (a step, a stride).
    pub fn step(&self) -> Result<usize, SettingError> {
        match self.count()? {
            0 => Err(self.out_of_range("a whole number of at least 1")),
            n => Ok(n),
        }
    }

    /// The value, given in degrees from 0 to 90 (an angle between directions, a direction's
    /// uncertainty), in radians.
    pub fn degrees(&self) -> Result<f64, SettingError> {
        self.within(0.0, 90.0, "from 0 to 90 degrees").map(f64::to_radians)
    }

    /// The value, when it is at least 0 (a distance, a cap, a margin).
    pub fn non_negative(&self) -> Result<f64, SettingError> {
        self.within(0.0, f64::INFINITY, "at least 0")
    }

    /// The value, when it is above 0 (a noise scale, a step along a wall).
    pub fn positive(&self) -> Result<f64, SettingError> {
        match self.value > 0.0 {
            true => Ok(self.value),
            false => Err(self.out_of_range("above 0")),
        }
    }

    /// The value, when it is a fraction from 0 to 1 (of beams, of a line).
    pub fn fraction(&self) -> Result<f64, SettingError> {
        self.within(0.0, 1.0, "a fraction from 0 to 1")
    }

    /// The value, when it is at least `lo` and at most `hi`.
    pub fn within(&self, lo: f64, hi: f64, range: &'static str) -> Result<f64, SettingError> {
        match (lo..=hi).contains(&self.value) {
            true => Ok(self.value),
            false => Err(self.out_of_range(range)),
        }
    }

    fn out_of_range(&self, range: &'static str) -> SettingError {
        SettingError::OutOfRange { key: self.key.to_string(), value: self.value, range }
    }

    /// The value as a switch: 0 is off, anything else on.
    pub fn switch(&self) -> bool {
        self.value != 0.0
    }
}

impl SegmenterConfig {
    /// Every segmentation parameter settable by name. `wall_ends` and the error model's keys
    /// also concern localization, which must agree with segmentation on them.
    pub const SETTINGS: &'static [SettingSpec<SegmenterConfig>] = &[
        setting!(
            SegmenterConfig,
            "reach",
            Range::NonNegative,
            "how far a corner may lie beyond a line's visible end, metres",
            corner.reach
        ),
        setting!(
            SegmenterConfig,
            "long_reach",
            Range::NonNegative,
            "that reach between two long lines, metres",
            corner.long_reach
        ),
        setting!(
            SegmenterConfig,
            "long_line",
            Range::NonNegative,
            "a line at least this long is long (for long_reach), metres",
            corner.long_line
        ),
        setting!(
            SegmenterConfig,
            "min_arm",
            Range::NonNegative,
            "shortest visible arm of a corner, metres",
            corner.min_arm_length
        ),
        setting!(
            SegmenterConfig,
            "max_direction_sigma",
            Range::Degrees,
            "largest direction uncertainty of a corner's arm",
            corner.max_direction_sigma
        ),
        setting!(
            SegmenterConfig,
            "wall_ends",
            Range::Switch,
            "also match wall ends, ranked with the corners",
            ends.enabled
        ),
        setting!(
            SegmenterConfig,
            "merge_angle",
            Range::Degrees,
            "alpha: lines closer in direction than this are merged (section 4.3)",
            filter.merge_angle
        ),
        setting!(
            SegmenterConfig,
            "min_samples",
            Range::Count,
            "k: lines of fewer samples are dropped (section 4.3)",
            filter.min_samples
        ),
        setting!(
            SegmenterConfig,
            "averaging",
            Range::Step,
            "readings averaged into one sample (section 4.1)",
            averaging
        ),
        setting!(
            SegmenterConfig,
            "noise_tolerance",
            Range::NonNegative,
            "a scan this many times noisier than e(d) is segmented with e(d) widened to its noise (0: never)",
            noise_tolerance
        ),
        // a range sensor's error is never nil, however close the wall (eqs. 1-2)
        setting!(
            SegmenterConfig,
            "error_constant",
            Range::Positive,
            "e(d): the sensor's constant error, metres (eqs. 1-2)",
            error.constant
        ),
        setting!(
            SegmenterConfig,
            "error_proportional",
            Range::NonNegative,
            "e(d): the sensor's error per metre of range (0.01 = 1 %)",
            error.proportional
        ),
    ];

    /// Applies `s` when it names a segmentation parameter: `Ok(true)`; `Ok(false)` when it
    /// names none.
    pub fn set(&mut self, s: &Setting<'_>) -> Result<bool, SettingError> {
        set_by_table(Self::SETTINGS, self, s)
    }

    /// Applies every `KEY=VALUE` of `settings`, or none of them when one is malformed or
    /// names no segmentation parameter.
    pub fn apply<S: AsRef<str>>(&mut self, settings: &[S]) -> Result<(), SettingError> {
        let mut c = *self;
        for kv in settings {
            let s = Setting::parse(kv.as_ref())?;
            if !c.set(&s)? {
                return Err(SettingError::unknown(s.key, Self::SETTINGS.iter().map(|spec| spec.key)));
            }
        }
        *self = c;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_setting_is_a_key_and_a_finite_number() {
        assert_eq!(Setting::parse("reach=0.4"), Ok(Setting { key: "reach", value: 0.4 }));
        assert_eq!(Setting::parse(" reach = 2 "), Ok(Setting { key: "reach", value: 2.0 }));
        assert!(matches!(Setting::parse("reach"), Err(SettingError::NotKeyValue(_))));
        for bad in ["reach=", "reach=abc", "reach=NaN", "reach=inf"] {
            assert!(matches!(Setting::parse(bad), Err(SettingError::NotANumber { .. })), "{bad}");
        }
        let count = |kv| Setting::parse(kv).unwrap().count();
        assert_eq!(count("n=3"), Ok(3));
        for bad in ["n=-1", "n=2.5", "n=1e12"] {
            assert!(matches!(count(bad), Err(SettingError::NotACount { .. })), "{bad}");
        }
    }

    #[test]
    fn a_value_outside_its_parameter_s_range_is_refused_with_the_range() {
        let mut c = SegmenterConfig::default();
        let before = c;
        for bad in ["reach=-0.5", "max_direction_sigma=120", "merge_angle=-2", "averaging=0", "error_constant=0"] {
            let err = c.apply(&[bad]).unwrap_err();
            assert!(matches!(err, SettingError::OutOfRange { .. }), "{bad}: {err}");
        }
        let err = c.apply(&["error_proportional=-0.01"]).unwrap_err().to_string();
        assert_eq!(err, "setting error_proportional: -0.01 is out of range: it must be at least 0");
        assert_eq!(c, before);
        c.apply(&["reach=0", "max_direction_sigma=90", "averaging=2", "error_proportional=0"]).unwrap();
    }

    #[test]
    fn segmentation_settings_land_in_their_fields_and_others_are_refused() {
        let mut c = SegmenterConfig::default();
        c.apply(&["merge_angle=4", "min_samples=7", "error_constant=0.05", "wall_ends=0"]).unwrap();
        assert!((c.filter.merge_angle - 4f64.to_radians()).abs() < 1e-12);
        assert_eq!(c.filter.min_samples, 7);
        assert_eq!(c.error.constant, 0.05);
        assert!(!c.ends.enabled);
        let err = c.apply(&["screened=10"]).unwrap_err();
        assert!(err.to_string().contains("unknown setting \"screened\""), "{err}");
        assert!(err.to_string().contains("gema2 settings"), "{err}");
        // a typo is answered with the key it most likely meant
        let err = c.apply(&["merge_angel=3"]).unwrap_err();
        assert!(err.to_string().contains("(did you mean \"merge_angle\"?)"), "{err}");
        let err = c.apply(&["zzz=3"]).unwrap_err();
        assert!(!err.to_string().contains("did you mean"), "{err}");
        // settings with a refused one among them change nothing
        let before = c;
        assert!(c.apply(&["min_samples=9", "min_samples=-2"]).is_err());
        assert_eq!(c, before);
    }
}
