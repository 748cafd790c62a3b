//! The SCIP 2.0 driver over TCP against the emulated UST-10LX: the serial driver's fault tests
//! (a corrupt checksum, garbage, a dropped link), over Ethernet.

use acquire::scip::emulator::{EmulatorFaults, UrgEmulator};
use acquire::scip::{Encoding, ScipError, ScipModel, TcpSource, Urg};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// Readings the emulator sends: scan k, step i -> 500 + 7 i + k mm (an error code at i = 10).
fn ranges(k: u64) -> Vec<u32> {
    (0..1081u32).map(|i| if i == 10 { 7 } else { 500 + 7 * i + k as u32 }).collect()
}

/// The scan number a reading of step 0 says.
fn number(mm: u32) -> u64 {
    (mm - 500) as u64
}

struct Running {
    address: String,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// An emulated UST-10LX on a free port of 127.0.0.1, at 40 Hz.
fn start(model: ScipModel, faults: EmulatorFaults) -> Running {
    let mut k = 0;
    let mut emu = UrgEmulator::new(
        model,
        Box::new(move || {
            k += 1;
            ranges(k - 1)
        }),
        Duration::from_millis(25),
        faults,
    );
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let stop = Arc::new(AtomicBool::new(false));
    let s = Arc::clone(&stop);
    let thread = std::thread::spawn(move || emu.serve_clients(&listener, &s).unwrap());
    Running { address, stop, thread: Some(thread) }
}

fn open(address: &str) -> Urg<TcpStream> {
    let stream = TcpStream::connect(address).unwrap();
    stream.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
    Urg::new(stream, Duration::from_secs(2))
}

#[test]
fn a_ust_10lx_gives_1081_readings_over_270_degrees_as_it_reports_them() {
    let emu = start(ScipModel::UST_10LX, EmulatorFaults::default());
    let mut source = TcpSource::new(&emu.address);
    let scan = source.next_scan(&mut |wait| wait.is_zero()).expect("connected on the first attempt").unwrap();
    assert_eq!(scan.ranges.len(), 1081);
    let g = scan.geometry;
    assert!((g.angle(0).to_degrees() + 135.0).abs() < 1e-9, "{g:?}");
    assert!((g.angle(1080).to_degrees() - 135.0).abs() < 1e-9, "{g:?}");
    assert_eq!((g.range_min, g.range_max), (0.02, 10.0));
    assert_eq!(scan.ranges[10], 0.0, "an error code is an invalid reading");
    let k = number((scan.ranges[0] * 1000.0).round() as u32);
    assert!(scan.ranges.iter().enumerate().all(|(i, &r)| i == 10 || r == ranges(k)[i] as f32 / 1000.0));
    // the next scan is the next one the sensor measured
    let next = source.next_scan(&mut |_| true).unwrap().unwrap();
    assert_eq!(number((next.ranges[0] * 1000.0).round() as u32), k + 1);
    // a UTM-30LX reports its own limits, and the driver takes them
    let utm = start(ScipModel::UTM_30LX, EmulatorFaults::default());
    let scan = TcpSource::new(&utm.address).next_scan(&mut |_| true).unwrap().unwrap();
    assert_eq!((scan.ranges.len(), scan.geometry.range_min, scan.geometry.range_max), (1081, 0.1, 30.0));
}

#[test]
fn an_ethernet_sensor_has_no_bit_rate_to_change() {
    let emu = start(ScipModel::UST_10LX, EmulatorFaults::default());
    let mut urg = open(&emu.address);
    urg.connect().unwrap();
    let err = urg.set_bit_rate(115_200).unwrap_err().to_string();
    assert!(err.contains("04") && err.contains("cannot change its bit rate"), "{err}");
}

#[test]
fn a_corrupted_checksum_over_tcp_drops_that_scan_only() {
    let emu = start(ScipModel::UST_10LX, EmulatorFaults { corrupt_scan: Some(2), ..Default::default() });
    let mut urg = open(&emu.address);
    urg.connect().unwrap();
    urg.laser_on().unwrap();
    urg.start(Encoding::Three, 0, 1080, 1, 0).unwrap();
    let mut got = Vec::new();
    let mut dropped = 0;
    while got.len() < 5 {
        match urg.next_scan() {
            Ok(s) => got.push(number(s.ranges_mm[0])),
            Err(ScipError::Checksum(_)) => dropped += 1,
            Err(e) => panic!("{e}"),
        }
    }
    assert_eq!((dropped, urg.stats.checksum_drops), (1, 1));
    assert_eq!(got, vec![0, 1, 3, 4, 5], "scan 2 is missing, the stream went on");
}

#[test]
fn garbage_over_tcp_is_skipped() {
    let emu = start(ScipModel::UST_10LX, EmulatorFaults { garbage_before_scan: Some(1), ..Default::default() });
    let mut source = TcpSource::new(&emu.address);
    let got: Vec<u64> = (0..4)
        .map(|_| number((source.next_scan(&mut |_| true).unwrap().unwrap().ranges[0] * 1000.0).round() as u32))
        .collect();
    assert_eq!(got, vec![0, 1, 2, 3]);
    assert!(source.totals().resyncs >= 1);
    assert_eq!(source.reconnects, 0);
}

#[test]
fn a_dropped_connection_is_reconnected_and_streaming_resumes() {
    let emu = start(ScipModel::UST_10LX, EmulatorFaults { close_after_scans: Some(3), ..Default::default() });
    let mut source = TcpSource::new(&emu.address);
    let mut got = Vec::new();
    while got.len() < 8 {
        let scan = source.next_scan(&mut |_| true).unwrap().unwrap();
        got.push(number((scan.ranges[0] * 1000.0).round() as u32));
    }
    // the sensor measured on while no one was connected: the numbers jump, never go back
    assert_eq!(&got[..3], &[0, 1, 2]);
    assert!(got.windows(2).all(|w| w[1] > w[0]), "{got:?}");
    assert!(got[3..].windows(2).all(|w| w[1] == w[0] + 1), "streaming resumed: {got:?}");
    assert_eq!(source.totals().scans, 8);
}

#[test]
fn a_sensor_not_there_yet_is_waited_for_with_backoff() {
    // a port nothing listens on (bound, then closed)
    let address = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().to_string();
    let mut source = TcpSource::new(&address);
    let mut waits = Vec::new();
    let got = source.next_scan(&mut |wait| {
        if !wait.is_zero() {
            waits.push(wait);
        }
        waits.len() < 4
    });
    assert!(got.is_none(), "told to stop while waiting");
    assert_eq!(waits, [100, 200, 400, 800].map(Duration::from_millis));
    // an address without a port is not looked up (no packet leaves this machine), and is
    // retried the same way, in case it was a name not yet known
    let mut source = TcpSource::new("127.0.0.1");
    assert!(source.next_scan(&mut |wait| wait.is_zero()).is_none());
}
