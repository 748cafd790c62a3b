//! The SCIP 2.0 driver against the emulated URG-04LX on a pseudo-terminal.

use acquire::scip::emulator::{EmulatorFaults, ServeEnd, UrgEmulator};
use acquire::scip::{Encoding, ScipError, SerialSource, Urg};
use serialport::{SerialPort, TTYPort};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Readings the emulator sends: scan k, step i -> 500 + 7 i + k mm (an error code at i = 10).
fn ranges(k: u64) -> Vec<u32> {
    (0..682u32).map(|i| if i == 10 { 7 } else { 500 + 7 * i + k as u32 }).collect()
}

fn emulator(faults: EmulatorFaults) -> UrgEmulator {
    let mut k = 0;
    UrgEmulator::urg04lx(
        Box::new(move || {
            k += 1;
            ranges(k - 1)
        }),
        Duration::from_millis(20),
        faults,
    )
}

struct Running {
    path: String,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<ServeEnd>>,
    _slave: TTYPort,
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn start(mut emu: UrgEmulator) -> Running {
    let (mut master, slave) = TTYPort::pair().unwrap();
    master.set_timeout(Duration::from_millis(5)).unwrap();
    let path = slave.name().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let s = Arc::clone(&stop);
    let thread = std::thread::spawn(move || emu.serve(&mut master, &s).unwrap());
    Running { path, stop, thread: Some(thread), _slave: slave }
}

fn open(path: &str) -> Urg<TTYPort> {
    let port = serialport::new(path, 115_200).timeout(Duration::from_millis(500)).open_native().unwrap();
    Urg::new(port, Duration::from_secs(2))
}

#[test]
fn scans_arrive_with_the_ranges_the_emulator_sent() {
    let emu = start(emulator(EmulatorFaults::default()));
    let mut urg = open(&emu.path);
    let info = urg.connect().unwrap().clone();
    assert_eq!((info.dmin, info.dmax, info.ares, info.amin, info.amax, info.afrt), (20, 5600, 1024, 44, 725, 384));
    assert!(info.product.contains("URG-04LX"), "{info:?}");
    urg.laser_on().unwrap();
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    let first = urg.next_scan().unwrap();
    let second = urg.next_scan().unwrap();
    let k0 = first.ranges_mm[0] - 500;
    assert_eq!(first.ranges_mm, ranges(k0 as u64));
    assert_eq!(second.ranges_mm, ranges(k0 as u64 + 1));
    assert_eq!(first.error_codes()[7], 1);
    let scan = first.to_laser_scan(&info, 0.0);
    assert_eq!(scan.ranges.len(), 682);
    assert_eq!(scan.ranges[10], 0.0, "an error code is an invalid reading");
    assert!((scan.ranges[0] - first.ranges_mm[0] as f32 / 1000.0).abs() < 1e-6);
    assert!(scan.geometry.angle(340).abs() < 1e-9, "step 384 is straight ahead");
    // two-character readings and single scans too
    urg.stop().unwrap();
    urg.laser_on().unwrap();
    let single = urg.single_scan(Encoding::Two, 44, 725, 2).unwrap();
    assert_eq!(single.ranges_mm.len(), 341);
    assert!(urg.sensor_time().is_ok());
}

#[test]
fn a_sensor_still_speaking_scip_1_1_is_switched_to_scip_2_0() {
    let emu = start(emulator(EmulatorFaults { starts_in_scip11: true, ..Default::default() }));
    let mut urg = open(&emu.path);
    let info = urg.connect().unwrap().clone();
    assert_eq!((info.amin, info.amax), (44, 725));
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    assert_eq!(urg.next_scan().unwrap().ranges_mm.len(), 682);
}

#[test]
fn a_sensor_that_does_not_describe_itself_fully_still_scans() {
    let emu = start(emulator(EmulatorFaults { minimal_describe: true, ..Default::default() }));
    let mut urg = open(&emu.path);
    let info = urg.connect().unwrap().clone();
    // PP placed the beams; VV's bad line and II's refusal are noted, not fatal
    assert_eq!((info.ares, info.amin, info.amax, info.afrt), (1024, 44, 725, 384));
    assert!(info.product.contains("URG-04LX"), "VV's good lines still count: {info:?}");
    assert!(info.firmware.is_empty(), "{info:?}");
    assert_eq!(info.unanswered.len(), 2, "{:?}", info.unanswered);
    assert!(info.unanswered[0].starts_with("VV:") && info.unanswered[1].starts_with("II: status 0E"), "{info:?}");
    urg.laser_on().unwrap();
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    assert_eq!(urg.next_scan().unwrap().ranges_mm.len(), 682);
}

#[test]
fn a_sensor_left_in_time_adjust_mode_is_brought_out_of_it() {
    let emu = start(emulator(EmulatorFaults { starts_in_time_adjust: true, ..Default::default() }));
    let mut urg = open(&emu.path);
    urg.connect().unwrap();
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    assert_eq!(urg.next_scan().unwrap().ranges_mm.len(), 682);
    // reading the clock leaves the sensor out of time-adjust mode again
    urg.stop().unwrap();
    let t = urg.sensor_time().unwrap();
    assert!(urg.sensor_time().unwrap() >= t);
    urg.laser_on().unwrap();
    assert_eq!(urg.single_scan(Encoding::Two, 44, 725, 1).unwrap().ranges_mm.len(), 682);
}

#[test]
fn an_rs232_sensor_at_another_bit_rate_is_found_and_switched() {
    // powered up at 19200 bit/s; the host asks for 115200
    let emu = start(emulator(EmulatorFaults { rs232_bit_rate: Some(19_200), ..Default::default() }));
    let mut source = SerialSource::new(&emu.path, 115_200);
    // no retries: the first connection must find it
    let scan = source.next_scan(&mut |wait| wait.is_zero()).expect("connected on the first attempt").unwrap();
    assert_eq!(scan.ranges.len(), 682);
    // the sensor now runs at the requested rate: a client at that rate is answered directly
    drop(source);
    let mut urg = open(&emu.path);
    urg.connect().unwrap();
    let err = urg.set_bit_rate(12_345).unwrap_err().to_string();
    assert!(err.contains("SS012345") && err.contains("02") && err.contains("bit rate"), "{err}");
    urg.set_bit_rate(115_200).unwrap();
}

#[test]
fn impossible_scan_requests_are_refused_before_anything_is_sent() {
    let emu = start(emulator(EmulatorFaults::default()));
    let mut urg = open(&emu.path);
    urg.connect().unwrap();
    for (first, last, cluster, scans) in [(700, 44, 1, 0), (44, 10_000, 1, 0), (44, 725, 100, 0), (44, 725, 1, 100)] {
        let err = urg.start(Encoding::Three, first, last, cluster, scans).unwrap_err();
        assert!(matches!(err, ScipError::Malformed(_)), "{err}");
    }
    assert!(matches!(urg.single_scan(Encoding::Two, 725, 44, 1), Err(ScipError::Malformed(_))));
    // the link is untouched
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    assert_eq!(urg.next_scan().unwrap().ranges_mm.len(), 682);
}

#[test]
fn a_corrupted_checksum_drops_that_scan_only() {
    let emu = start(emulator(EmulatorFaults { corrupt_scan: Some(2), ..Default::default() }));
    let mut urg = open(&emu.path);
    urg.connect().unwrap();
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    let mut got = Vec::new();
    let mut dropped = 0;
    while got.len() < 5 {
        match urg.next_scan() {
            Ok(s) => got.push(s.ranges_mm[0] - 500),
            Err(ScipError::Checksum(_)) => dropped += 1,
            Err(e) => panic!("{e}"),
        }
    }
    assert_eq!(dropped, 1);
    assert_eq!(urg.stats.checksum_drops, 1);
    // scan 2 is missing, the stream went on
    assert_eq!(got, vec![0, 1, 3, 4, 5]);
}

#[test]
fn garbage_and_partial_lines_resynchronise() {
    let emu = start(emulator(EmulatorFaults { garbage_before_scan: Some(1), ..Default::default() }));
    let mut urg = open(&emu.path);
    urg.connect().unwrap();
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    let got: Vec<u32> = (0..4).map(|_| urg.next_scan().unwrap().ranges_mm[0] - 500).collect();
    assert_eq!(got, vec![0, 1, 2, 3]);
    assert!(urg.stats.resyncs >= 1);
}

#[test]
fn a_laser_fault_is_a_clear_error() {
    let emu = start(emulator(EmulatorFaults { laser_broken: true, ..Default::default() }));
    let mut urg = open(&emu.path);
    urg.connect().unwrap();
    let err = urg.laser_on().unwrap_err().to_string();
    assert!(err.contains("BM") && err.contains("01") && err.contains("laser"), "{err}");
    drop(urg);
    let mut source = SerialSource::new(&emu.path, 115_200);
    let err = source.next_scan(&mut |_| true).unwrap().unwrap_err().to_string();
    assert!(err.contains("laser"), "{err}");
}

#[test]
fn timestamps_keep_increasing_across_the_24_bit_wrap() {
    let emu = start(emulator(EmulatorFaults { start_time_ms: (1 << 24) - 120, ..Default::default() }));
    let mut urg = open(&emu.path);
    urg.connect().unwrap();
    urg.start(Encoding::Three, 44, 725, 1, 0).unwrap();
    let stamps: Vec<u64> = (0..12).map(|_| urg.next_scan().unwrap().timestamp_ms).collect();
    assert!(stamps.windows(2).all(|w| w[1] > w[0]), "{stamps:?}");
    assert!(*stamps.last().unwrap() > 1 << 24, "{stamps:?}");
}

#[test]
fn the_port_closing_mid_stream_is_survived() {
    // the emulator serves 3 scans, closes its pty, and comes back on a new one behind the same
    // path (a symlink, as udev rules give a real sensor)
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("urg");
    let link_s = link.to_str().unwrap().to_owned();
    let stop = Arc::new(AtomicBool::new(false));
    let s = Arc::clone(&stop);
    let l = link.clone();
    let server = std::thread::spawn(move || -> Result<(), String> {
        let mut emu = emulator(EmulatorFaults { close_after_scans: Some(3), ..Default::default() });
        for round in 0..2 {
            // a pty can be briefly unavailable on a loaded machine: retry
            let mut pair = Err(String::new());
            for _ in 0..20 {
                pair = TTYPort::pair().map_err(|e| format!("round {round}: pty: {e}"));
                if pair.is_ok() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
            let (mut master, slave) = pair?;
            master.set_timeout(Duration::from_millis(5)).map_err(|e| format!("round {round}: {e}"))?;
            let name = slave.name().ok_or(format!("round {round}: pty without a name"))?;
            // replace the link atomically: a client never sees it missing
            let tmp = l.with_extension("new");
            let _ = std::fs::remove_file(&tmp);
            std::os::unix::fs::symlink(&name, &tmp).map_err(|e| format!("round {round}: link: {e}"))?;
            std::fs::rename(&tmp, &l).map_err(|e| format!("round {round}: link: {e}"))?;
            if round == 1 {
                emu.faults.close_after_scans = None;
            }
            let mut end = emu.serve(&mut master, &s).map_err(|e| format!("round {round}: serve: {e}"))?;
            // like a real sensor (and gema2 emulate-urg), the second round keeps serving when a
            // client goes away, until told to stop
            while round == 1 && end == ServeEnd::PortClosed {
                std::thread::sleep(Duration::from_millis(20));
                end = emu.serve(&mut master, &s).map_err(|e| format!("round {round}: serve: {e}"))?;
            }
            drop(master);
            drop(slave);
            if end == ServeEnd::Stopped {
                return Ok(());
            }
            std::thread::sleep(Duration::from_millis(300));
        }
        Ok(())
    });
    let deadline = Instant::now() + Duration::from_secs(20);
    while !link.exists() {
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut source = SerialSource::new(&link_s, 115_200);
    let mut scans = 0;
    while scans < 8 && Instant::now() < deadline {
        match source.next_scan(&mut |wait| {
            std::thread::sleep(wait);
            Instant::now() < deadline
        }) {
            Some(Ok(_)) => scans += 1,
            Some(Err(e)) => panic!("{e}"),
            None => break,
        }
    }
    stop.store(true, Ordering::Relaxed);
    let served = server.join().map_err(|_| "the emulator thread panicked".to_owned()).and_then(|r| r);
    assert_eq!(scans, 8, "emulator: {served:?}");
    assert!(source.reconnects >= 1 || source.stats.scans >= 3, "never lost the port?");
}
