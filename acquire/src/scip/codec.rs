//! SCIP 2.0 character encodings and checksums.
//!
//! Values are sent as 2, 3 or 4 characters of 6 bits each (character = bits + 0x30), most
//! significant first. A line's checksum character is `(sum of its bytes & 0x3F) + 0x30`. Scan
//! data is cut into lines of at most 64 characters, each with its own checksum; a value may
//! straddle two lines.

use super::ScipError;

/// Most data characters on one line.
pub const BLOCK: usize = 64;

/// The checksum character of `bytes`.
pub fn checksum(bytes: &[u8]) -> u8 {
    (bytes.iter().fold(0u8, |s, &b| s.wrapping_add(b)) & 0x3F) + 0x30
}

/// Decodes one value of `chars.len()` characters.
pub fn decode(chars: &[u8]) -> Result<u32, ScipError> {
    let mut v = 0u32;
    for &c in chars {
        if !(0x30..0x70).contains(&c) {
            return Err(ScipError::Malformed(format!("byte 0x{c:02x} is not a SCIP data character")));
        }
        v = (v << 6) | (c - 0x30) as u32;
    }
    Ok(v)
}

/// Appends `value` encoded in `width` characters.
pub fn encode(value: u32, width: usize, out: &mut Vec<u8>) {
    for k in (0..width).rev() {
        out.push(((value >> (6 * k)) & 0x3F) as u8 + 0x30);
    }
}

/// Splits encoded data into SCIP lines (each at most 64 characters, then its checksum, then
/// LF).
pub fn data_lines(data: &[u8], out: &mut Vec<u8>) {
    for chunk in data.chunks(BLOCK) {
        out.extend_from_slice(chunk);
        out.push(checksum(chunk));
        out.push(b'\n');
    }
}

/// Verifies a line that ends in its checksum character and returns the data before it.
pub fn verified(line: &[u8]) -> Result<&[u8], ScipError> {
    let Some((&sum, data)) = line.split_last() else {
        return Err(ScipError::Malformed("empty line where data was expected".into()));
    };
    if checksum(data) != sum {
        return Err(ScipError::Checksum(String::from_utf8_lossy(line).into_owned()));
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_specs_examples() {
        // SCIP 2.0: "1Dh" encodes 5432, "CB" encodes 1234
        assert_eq!(decode(b"1Dh").unwrap(), 5432);
        assert_eq!(decode(b"CB").unwrap(), 1234);
        let mut v = Vec::new();
        encode(5432, 3, &mut v);
        assert_eq!(v, b"1Dh");
        assert_eq!(checksum(b"00"), b'P');
        assert!(decode(b"1~").is_err());
    }

    proptest! {
        #[test]
        fn values_round_trip(v in 0u32..(1 << 24), width in 2usize..=4) {
            let v = v & ((1 << (6 * width)) - 1);
            let mut out = Vec::new();
            encode(v, width, &mut out);
            prop_assert_eq!(decode(&out).unwrap(), v);
        }
    }
}
