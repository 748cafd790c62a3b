//! The Hokuyo models the emulator can be, each described as its `PP` answer describes it: steps
//! in a turn, the measurable steps, the front step, the range limits and the motor speed. The
//! driver never reads these: it takes whatever a sensor reports.

use laser::ScanGeometry;

/// A SCIP 2.0 sensor's description, as `PP` reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScipModel {
    /// `MODL` and the product name `VV` reports.
    pub name: &'static str,
    pub product: &'static str,
    /// Shortest and longest range, mm (`DMIN`, `DMAX`).
    pub dmin: u32,
    pub dmax: u32,
    /// Steps in a full turn, first and last measurable step, the front step.
    pub ares: u32,
    pub amin: u32,
    pub amax: u32,
    pub afrt: u32,
    /// Motor speed, rpm (`SCAN`): one scan a turn.
    pub rpm: u32,
    /// Reached over RS-232 or USB (`SS` means something) rather than Ethernet.
    pub serial: bool,
}

impl ScipModel {
    /// URG-04LX: 682 readings over 240 degrees, 0.02-5.6 m, 10 Hz; USB or RS-232.
    pub const URG_04LX: ScipModel = ScipModel {
        name: "URG-04LX(Hokuyo Automatic Co.,Ltd.)",
        product: "SOKUIKI Sensor URG-04LX",
        dmin: 20,
        dmax: 5600,
        ares: 1024,
        amin: 44,
        amax: 725,
        afrt: 384,
        rpm: 600,
        serial: true,
    };

    /// UST-10LX: 1081 readings over 270 degrees, 0.02-10 m, 40 Hz; Ethernet.
    pub const UST_10LX: ScipModel = ScipModel {
        name: "UST-10LX(Hokuyo Automatic Co.,Ltd.)",
        product: "Hokuyo UST-10LX",
        dmin: 20,
        dmax: 10_000,
        ares: 1440,
        amin: 0,
        amax: 1080,
        afrt: 540,
        rpm: 2400,
        serial: false,
    };

    /// UTM-30LX-EW: 1081 readings over 270 degrees, 0.1-30 m, 40 Hz; Ethernet.
    pub const UTM_30LX: ScipModel = ScipModel {
        name: "UTM-30LX-EW(Hokuyo Automatic Co.,Ltd.)",
        product: "Hokuyo UTM-30LX-EW",
        dmin: 100,
        dmax: 30_000,
        ares: 1440,
        amin: 0,
        amax: 1080,
        afrt: 540,
        rpm: 2400,
        serial: false,
    };

    /// Every model, with the name `--model` takes.
    pub const ALL: [(&'static str, ScipModel); 3] =
        [("urg-04lx", Self::URG_04LX), ("ust-10lx", Self::UST_10LX), ("utm-30lx", Self::UTM_30LX)];

    /// The model `--model` names.
    pub fn named(name: &str) -> Option<ScipModel> {
        Self::ALL.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|&(_, m)| m)
    }

    /// Readings of a whole scan (every measurable step).
    pub fn readings(&self) -> usize {
        (self.amax - self.amin + 1) as usize
    }

    /// Time of one turn, milliseconds.
    pub fn period_ms(&self) -> u64 {
        (60_000 / self.rpm.max(1)) as u64
    }

    /// Where its readings point and how far they reach.
    pub fn geometry(&self) -> ScanGeometry {
        let step = std::f64::consts::TAU / self.ares as f64;
        ScanGeometry {
            angle_min: (self.amin as f64 - self.afrt as f64) * step,
            angle_increment: step,
            range_min: self.dmin as f64 / 1000.0,
            range_max: self.dmax as f64 / 1000.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_models_have_their_datasheet_fields_of_view() {
        for (name, fov, beams, hz) in
            [("urg-04lx", 239.4, 682, 10), ("ust-10lx", 270.0, 1081, 40), ("utm-30lx", 270.0, 1081, 40)]
        {
            let m = ScipModel::named(name).unwrap();
            let g = m.geometry();
            assert_eq!(m.readings(), beams);
            let span = g.angle(beams - 1) - g.angle(0);
            assert!((span.to_degrees() - fov).abs() < 0.1, "{name}: {}", span.to_degrees());
            assert!(g.angle((m.afrt - m.amin) as usize).abs() < 1e-12, "{name}: the front step looks ahead");
            assert_eq!(1000 / m.period_ms(), hz);
        }
        assert_eq!(ScipModel::named("UST-10LX"), Some(ScipModel::UST_10LX));
        assert_eq!(ScipModel::named("lms200"), None);
    }
}
