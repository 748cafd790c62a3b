//! The SCIP decoder on arbitrary bytes: it may refuse them, it must never panic.

use acquire::scip::frame::{read_frame, LineReader};
use acquire::scip::{Encoding, Urg};
use proptest::prelude::*;
use std::io::{Cursor, Read, Write};
use std::time::Duration;

/// Reads canned bytes; writes vanish.
struct Canned(Cursor<Vec<u8>>);

impl Read for Canned {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl Write for Canned {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Bytes that look like SCIP often enough to reach deep into the decoder.
fn scipish() -> impl Strategy<Value = Vec<u8>> {
    let piece = prop_oneof![
        Just(b"MD0044072501000\n".to_vec()),
        Just(b"99b\n".to_vec()),
        Just(b"00P\n".to_vec()),
        Just(b"\n".to_vec()),
        Just(b"0000\x30\n".to_vec()),
        proptest::collection::vec(0x30u8..0x70, 0..70).prop_map(|mut v| {
            v.push(b'\n');
            v
        }),
        proptest::collection::vec(any::<u8>(), 0..20),
    ];
    proptest::collection::vec(piece, 0..30).prop_map(|v| v.concat())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 100_000, ..ProptestConfig::default() })]
    #[test]
    fn frames_and_scans_never_panic(bytes in scipish()) {
        let mut r = LineReader::new(Cursor::new(bytes.clone()));
        let mut resyncs = 0;
        for _ in 0..50 {
            if read_frame(&mut r, &mut resyncs).is_err() {
                break;
            }
        }
        // the same bytes as a stream of scans
        let mut urg = Urg::new(Canned(Cursor::new(bytes)), Duration::from_millis(1));
        let _ = urg.start(Encoding::Three, 44, 725, 1, 0);
        for _ in 0..20 {
            if urg.next_scan().is_err() {
                break;
            }
        }
    }
}

proptest! {
    /// Every info line a sensor can send parses back to its key and value, whatever bytes its
    /// encoded value and its checksum are: both range over `0`..`o`, which holds `;`.
    #[test]
    fn an_info_line_holding_semicolons_parses(time in 0u32..(1 << 24), key in "[A-Z]{4}", text in "[ -~]{0,20}") {
        use acquire::scip::codec::{checksum, encode};
        use acquire::scip::driver::parse_info_line;
        let mut encoded = Vec::new();
        encode(time, 4, &mut encoded);
        for value in [String::from_utf8(encoded).unwrap(), text] {
            let body = format!("{key}:{value}");
            let mut line = body.clone().into_bytes();
            line.push(b';');
            line.push(checksum(body.as_bytes()));
            prop_assert_eq!(parse_info_line(&line).unwrap(), (key.clone(), value));
        }
    }
}
