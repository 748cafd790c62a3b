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
    #[error("unknown setting {key:?}; known here: {}", known.join(", "))]
    Unknown { key: String, known: Vec<&'static str> },
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
    /// The keys [`set`](Self::set) knows.
    pub const SETTINGS: &'static [&'static str] = &[
        "reach",
        "long_reach",
        "long_line",
        "min_arm",
        "max_direction_sigma (degrees)",
        "wall_ends (0 or 1)",
        "merge_angle (degrees)",
        "min_samples",
        "averaging (readings per sample, section 4.1)",
        "noise_tolerance (0: never widen e(d) to a noisier scan's measured noise)",
        "error_constant",
        "error_proportional",
    ];

    /// Applies `s` when it names a segmentation parameter: `Ok(true)`; `Ok(false)` when it
    /// names none. `wall_ends` and the error model's keys also concern localization, which
    /// must agree with segmentation on them.
    pub fn set(&mut self, s: &Setting<'_>) -> Result<bool, SettingError> {
        match s.key {
            "reach" => self.corner.reach = s.non_negative()?,
            "long_reach" => self.corner.long_reach = s.non_negative()?,
            "long_line" => self.corner.long_line = s.non_negative()?,
            "min_arm" => self.corner.min_arm_length = s.non_negative()?,
            "max_direction_sigma" => self.corner.max_direction_sigma = s.degrees()?,
            "wall_ends" => self.ends.enabled = s.switch(),
            "merge_angle" => self.filter.merge_angle = s.degrees()?,
            "min_samples" => self.filter.min_samples = s.count()? as u32,
            "averaging" => self.averaging = s.step()?,
            "noise_tolerance" => self.noise_tolerance = s.non_negative()?,
            // a range sensor's error is never nil, however close the wall (eqs. 1-2)
            "error_constant" => self.error.constant = s.positive()?,
            "error_proportional" => self.error.proportional = s.non_negative()?,
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// Applies every `KEY=VALUE` of `settings`, or none of them when one is malformed or
    /// names no segmentation parameter.
    pub fn apply<S: AsRef<str>>(&mut self, settings: &[S]) -> Result<(), SettingError> {
        let mut c = *self;
        for kv in settings {
            let s = Setting::parse(kv.as_ref())?;
            if !c.set(&s)? {
                return Err(SettingError::Unknown { key: s.key.to_string(), known: Self::SETTINGS.to_vec() });
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
        assert!(err.to_string().contains("merge_angle"), "{err}");
        // settings with a refused one among them change nothing
        let before = c;
        assert!(c.apply(&["min_samples=9", "min_samples=-2"]).is_err());
        assert_eq!(c, before);
    }
}
