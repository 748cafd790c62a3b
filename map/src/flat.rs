//! The map model as one block of bytes that a reader uses where it lies: how the map server
//! shares a model with every localizer through shared memory.
//!
//! The layout is a sequence of fields in the order each type's [`Flat::put`] writes them:
//! - a scalar is 8 bytes (`u64`, `f64`, a `usize` as `u64`), native byte order;
//! - an array is its length as a `u64`, zero bytes up to the next multiple of [`ALIGN`], then its
//!   values as they lie in memory ([`Plain`] types only: no pointers, no padding).
//!
//! The block starts [`ALIGN`]-aligned, so every array lies aligned in it, and a reader's
//! [`Slab`]s view the arrays in place: nothing is copied or decoded but the scalars and a few
//! small lists ([`FlatReader::copied`] counts their bytes). A reader checks every length and
//! offset against the block, and each type checks what its own code relies on (a grid's
//! lists within its items, indices within their arrays), so a damaged block is refused with an
//! error, never read out of bounds. The layout's version is
//! [`crate::model::MODEL_LAYOUT`]; a change to any `put` must raise it.

use crate::slab::{Owner, Plain, Slab};
use std::ptr::NonNull;

/// The alignment of the block and of every array in it, bytes.
pub const ALIGN: usize = 16;

/// Why a block is not a model this reader can use.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("map model: {0}")]
pub struct FlatError(pub String);

impl FlatError {
    pub fn new(what: impl Into<String>) -> Self {
        FlatError(what.into())
    }
}

/// A type that writes itself into a block and reads itself from one (see the module docs).
pub trait Flat: Sized {
    fn put(&self, w: &mut FlatWriter);
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError>;
}

/// Builds a block.
#[derive(Default)]
pub struct FlatWriter {
    bytes: Vec<u8>,
}

impl FlatWriter {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn put_u64(&mut self, v: u64) {
        self.bytes.extend_from_slice(&v.to_ne_bytes());
    }

    pub fn put_usize(&mut self, v: usize) {
        self.put_u64(v as u64);
    }

    pub fn put_f64(&mut self, v: f64) {
        self.put_u64(v.to_bits());
    }

    pub fn put_bool(&mut self, v: bool) {
        self.put_u64(u64::from(v));
    }

    /// An array: its length, padding to [`ALIGN`], its values.
    pub fn put_slice<T: Plain>(&mut self, values: &[T]) {
        self.put_usize(values.len());
        self.bytes.resize(self.bytes.len().next_multiple_of(ALIGN), 0);
        // SAFETY: `T: Plain` has no padding, so all of its bytes are initialized
        let raw = unsafe { std::slice::from_raw_parts(values.as_ptr().cast::<u8>(), std::mem::size_of_val(values)) };
        self.bytes.extend_from_slice(raw);
    }

    /// The block so far.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
}

/// Reads a block in place: its arrays become [`Slab`]s that view it, kept alive by its owner.
pub struct FlatReader<'a> {
    bytes: &'a [u8],
    pos: usize,
    owner: Owner,
    copied: usize,
}

impl<'a> FlatReader<'a> {
    /// A reader of `bytes`.
    ///
    /// # Safety
    /// `bytes` must stay valid and unwritten for as long as `owner`, or any clone of it, lives:
    /// the slabs read from it view it and keep only `owner`.
    pub unsafe fn new(bytes: &'a [u8], owner: Owner) -> Result<Self, FlatError> {
        if !(bytes.as_ptr() as usize).is_multiple_of(ALIGN) {
            return Err(FlatError::new(format!("the block does not start {ALIGN}-byte aligned")));
        }
        Ok(FlatReader { bytes, pos: 0, owner, copied: 0 })
    }

    /// A reader of a copy of `bytes` held by the reader's slabs: for a block that came from
    /// elsewhere than shared memory (a file, a test).
    pub fn of_copy(bytes: &[u8]) -> FlatReader<'static> {
        let words: Vec<u128> = bytes
            .chunks(16)
            .map(|c| {
                let mut w = [0u8; 16];
                w[..c.len()].copy_from_slice(c);
                u128::from_ne_bytes(w)
            })
            .collect();
        let words: Box<[u128]> = words.into_boxed_slice();
        // SAFETY: the boxed words never move or change while the Arc lives, and u128 is
        // 16-byte aligned on every target this builds for (checked by `new`)
        let view: &'static [u8] = unsafe { std::slice::from_raw_parts(words.as_ptr().cast::<u8>(), bytes.len()) };
        let owner: Owner = std::sync::Arc::new(words);
        // SAFETY: as above
        match unsafe { FlatReader::new(view, owner) } {
            Ok(r) => r,
            // u128 less aligned than ALIGN: read from an owned, aligned copy anyway
            Err(_) => unreachable!("a boxed [u128] is 16-byte aligned"),
        }
    }

    /// Bytes read so far.
    pub fn position(&self) -> usize {
        self.pos
    }

    /// Bytes copied out of the block rather than viewed in it.
    pub fn copied(&self) -> usize {
        self.copied
    }

    fn short(&self, what: &str, need: usize) -> FlatError {
        FlatError::new(format!("{what}: needs {need} bytes at offset {}, the block has {}", self.pos, self.bytes.len()))
    }

    pub fn take_u64(&mut self, what: &str) -> Result<u64, FlatError> {
        let end = self.pos.checked_add(8).filter(|&e| e <= self.bytes.len()).ok_or_else(|| self.short(what, 8))?;
        let mut b = [0u8; 8];
        b.copy_from_slice(&self.bytes[self.pos..end]);
        self.pos = end;
        Ok(u64::from_ne_bytes(b))
    }

    pub fn take_usize(&mut self, what: &str) -> Result<usize, FlatError> {
        let v = self.take_u64(what)?;
        usize::try_from(v).map_err(|_| FlatError::new(format!("{what}: {v} does not fit this machine")))
    }

    pub fn take_f64(&mut self, what: &str) -> Result<f64, FlatError> {
        Ok(f64::from_bits(self.take_u64(what)?))
    }

    /// A finite number.
    pub fn take_finite(&mut self, what: &str) -> Result<f64, FlatError> {
        let v = self.take_f64(what)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(FlatError::new(format!("{what}: {v} is not a finite number")))
        }
    }

    pub fn take_bool(&mut self, what: &str) -> Result<bool, FlatError> {
        match self.take_u64(what)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(FlatError::new(format!("{what}: {v} is neither 0 nor 1"))),
        }
    }

    /// An array, viewed where it lies.
    pub fn take_slab<T: Plain>(&mut self, what: &str) -> Result<Slab<T>, FlatError> {
        let len = self.take_usize(what)?;
        let start = self.pos.next_multiple_of(ALIGN);
        let size = len.checked_mul(std::mem::size_of::<T>()).ok_or_else(|| self.short(what, usize::MAX))?;
        let end = start.checked_add(size).filter(|&e| e <= self.bytes.len()).ok_or_else(|| self.short(what, size))?;
        let ptr = self.bytes[start..end].as_ptr();
        if !(ptr as usize).is_multiple_of(std::mem::align_of::<T>()) {
            return Err(FlatError::new(format!("{what}: misaligned at offset {start}")));
        }
        self.pos = end;
        let ptr = NonNull::new(ptr as *mut T).ok_or_else(|| FlatError::new(format!("{what}: null")))?;
        // SAFETY: in bounds and aligned (checked above); `T: Plain` is valid for any bytes;
        // `new`'s contract keeps the bytes alive and unwritten while the owner lives
        Ok(unsafe { Slab::shared(ptr, len, self.owner.clone()) })
    }

    /// An array copied out: for small lists the model keeps as `Vec`s.
    pub fn take_vec<T: Plain>(&mut self, what: &str) -> Result<Vec<T>, FlatError> {
        let slab = self.take_slab::<T>(what)?;
        self.copied += slab.byte_len();
        Ok(slab.to_vec())
    }

    /// Whether every byte has been read: a block with bytes left over was written by another
    /// layout.
    pub fn finish(&self) -> Result<(), FlatError> {
        if self.pos.next_multiple_of(ALIGN) >= self.bytes.len() {
            Ok(())
        } else {
            Err(FlatError::new(format!("{} bytes left after the model", self.bytes.len() - self.pos)))
        }
    }
}

impl<T: Plain> Flat for Slab<T> {
    fn put(&self, w: &mut FlatWriter) {
        w.put_slice(self);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        r.take_slab(std::any::type_name::<T>())
    }
}

/// A value or none: a yes/no, then the value when there is one.
impl<T: Flat> Flat for Option<T> {
    fn put(&self, w: &mut FlatWriter) {
        w.put_bool(self.is_some());
        if let Some(v) = self {
            v.put(w);
        }
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        if r.take_bool(std::any::type_name::<T>())? {
            T::take(r).map(Some)
        } else {
            Ok(None)
        }
    }
}

/// Checks that every value of `items` is below `bound`: indices into an array of that length.
pub fn check_indices(what: &str, items: &[u32], bound: usize) -> Result<(), FlatError> {
    match items.iter().position(|&i| i as usize >= bound) {
        None => Ok(()),
        Some(k) => Err(FlatError::new(format!("{what}: entry {k} is {}, past the {bound} there are", items[k]))),
    }
}

/// Checks that an array read for a grid of `cells` has that many values.
pub fn check_len(what: &str, len: usize, expected: usize) -> Result<(), FlatError> {
    if len == expected {
        Ok(())
    } else {
        Err(FlatError::new(format!("{what}: {len} values where the grid has {expected}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalars_and_arrays_read_back_and_arrays_lie_in_the_block() {
        let mut w = FlatWriter::new();
        w.put_u64(7);
        w.put_slice(&[1.5f64, -2.0]);
        w.put_bool(true);
        w.put_slice::<u8>(&[3, 4, 5]);
        w.put_slice::<u32>(&[9]);
        let mut r = FlatReader::of_copy(w.bytes());
        assert_eq!(r.take_u64("a").unwrap(), 7);
        let a = r.take_slab::<f64>("b").unwrap();
        assert!(a.is_shared());
        assert_eq!(&*a, &[1.5, -2.0]);
        assert!(r.take_bool("c").unwrap());
        assert_eq!(&*r.take_slab::<u8>("d").unwrap(), &[3, 4, 5]);
        assert_eq!(r.take_vec::<u32>("e").unwrap(), vec![9]);
        assert_eq!(r.copied(), 4);
        r.finish().unwrap();
    }

    #[test]
    fn a_short_or_damaged_block_is_an_error_not_a_read_past_its_end() {
        let mut w = FlatWriter::new();
        w.put_slice(&[1u64, 2, 3]);
        let bytes = w.bytes().to_vec();
        for cut in 0..bytes.len() {
            let mut r = FlatReader::of_copy(&bytes[..cut]);
            assert!(r.take_slab::<u64>("x").is_err(), "cut at {cut}");
        }
        // a length near usize::MAX must not overflow
        let mut huge = bytes.clone();
        huge[..8].copy_from_slice(&u64::MAX.to_ne_bytes());
        assert!(FlatReader::of_copy(&huge).take_slab::<u64>("x").is_err());
        let mut bad_bool = FlatWriter::new();
        bad_bool.put_u64(2);
        assert!(FlatReader::of_copy(bad_bool.bytes()).take_bool("b").is_err());
        assert!(check_indices("i", &[0, 1, 5], 5).is_err());
        assert!(check_indices("i", &[0, 1, 4], 5).is_ok());
    }
}
