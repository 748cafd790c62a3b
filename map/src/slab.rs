//! Arrays the map model holds either in its own memory or in memory shared with other
//! processes, read in place.
//!
//! The map server builds a map's model once and publishes it as one block of bytes in shared
//! memory ([`crate::flat`]); every localizer reads that block where it lies. The model's large
//! arrays (corners, wall grids, distance field, free-space bits) are [`Slab`]s: a `Vec` when the
//! model was built here, a view of the shared block when it came from the server. Either way
//! they read as slices, so the localizer's code does not know which.

use std::any::Any;
use std::fmt;
use std::ops::Deref;
use std::ptr::NonNull;
use std::sync::Arc;

/// A type whose values are plain bytes: no pointers, no padding, and every bit pattern a valid
/// value. Only such types are written to and read from shared memory as they lie.
///
/// # Safety
/// The implementing type must be `#[repr(C)]` (or a primitive) with no padding bytes, hold no
/// pointer or reference, and be valid for any bit pattern of its size.
pub unsafe trait Plain: Copy + Send + Sync + 'static {}

// SAFETY: primitives without padding, valid for every bit pattern.
unsafe impl Plain for u8 {}
unsafe impl Plain for u16 {}
unsafe impl Plain for u32 {}
unsafe impl Plain for u64 {}
unsafe impl Plain for i64 {}
unsafe impl Plain for f64 {}

/// What keeps shared bytes alive and unchanged while a [`Slab`] views them: the shared-memory
/// sample the bytes lie in, or a buffer of this process.
pub type Owner = Arc<dyn Any + Send + Sync>;

/// An array of `T` owned here or viewed in memory an [`Owner`] keeps alive. Reads as `[T]`.
pub struct Slab<T: Plain> {
    inner: Inner<T>,
}

enum Inner<T: Plain> {
    Owned(Vec<T>),
    Shared { ptr: NonNull<T>, len: usize, _owner: Owner },
}

// SAFETY: a shared slab only reads memory that its owner keeps alive and that nobody writes
// while an owner lives (the map server never writes a sample after sending it); `T: Plain`
// is `Send + Sync`.
unsafe impl<T: Plain> Send for Slab<T> {}
unsafe impl<T: Plain> Sync for Slab<T> {}

impl<T: Plain> Slab<T> {
    /// A view of `len` values at `ptr`, which `owner` keeps alive and unchanged.
    ///
    /// # Safety
    /// `ptr` must be aligned for `T`, point to `len` initialized values of `T` that stay valid
    /// and unwritten for as long as `owner` (or a clone of it) lives.
    pub unsafe fn shared(ptr: NonNull<T>, len: usize, owner: Owner) -> Self {
        Slab { inner: Inner::Shared { ptr, len, _owner: owner } }
    }

    /// Whether the values lie in memory this slab does not own.
    pub fn is_shared(&self) -> bool {
        matches!(self.inner, Inner::Shared { .. })
    }

    /// The values to change: a shared slab first copies them into memory of its own.
    pub fn to_mut(&mut self) -> &mut Vec<T> {
        if let Inner::Shared { .. } = self.inner {
            self.inner = Inner::Owned(self.to_vec());
        }
        match &mut self.inner {
            Inner::Owned(v) => v,
            Inner::Shared { .. } => unreachable!("made owned above"),
        }
    }

    /// The bytes the values take.
    pub fn byte_len(&self) -> usize {
        std::mem::size_of_val::<[T]>(self)
    }
}

impl<T: Plain> Deref for Slab<T> {
    type Target = [T];
    #[inline]
    fn deref(&self) -> &[T] {
        match &self.inner {
            Inner::Owned(v) => v,
            // SAFETY: `shared`'s contract: aligned, initialized, alive while the owner is
            Inner::Shared { ptr, len, .. } => unsafe { std::slice::from_raw_parts(ptr.as_ptr(), *len) },
        }
    }
}

impl<T: Plain> From<Vec<T>> for Slab<T> {
    fn from(v: Vec<T>) -> Self {
        Slab { inner: Inner::Owned(v) }
    }
}

impl<T: Plain> Default for Slab<T> {
    fn default() -> Self {
        Vec::new().into()
    }
}

impl<T: Plain> Clone for Slab<T> {
    fn clone(&self) -> Self {
        match &self.inner {
            Inner::Owned(v) => v.clone().into(),
            Inner::Shared { ptr, len, _owner } => {
                Slab { inner: Inner::Shared { ptr: *ptr, len: *len, _owner: Arc::clone(_owner) } }
            }
        }
    }
}

impl<T: Plain + PartialEq> PartialEq for Slab<T> {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl<T: Plain> fmt::Debug for Slab<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let place = if self.is_shared() { "shared" } else { "owned" };
        write!(f, "Slab<{}>({} values, {place})", std::any::type_name::<T>(), self.len())
    }
}

impl<'a, T: Plain> IntoIterator for &'a Slab<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shared_slab_reads_its_owners_memory_and_copies_only_to_change() {
        let owner: Arc<Vec<u32>> = Arc::new(vec![1, 2, 3, 4]);
        let ptr = NonNull::new(owner.as_ptr() as *mut u32).expect("a vec's pointer is not null");
        // SAFETY: the vec is kept alive by the owner and never written
        let mut s = unsafe { Slab::shared(ptr, 3, owner.clone()) };
        assert!(s.is_shared());
        assert_eq!(&*s, &[1, 2, 3]);
        assert_eq!(Arc::strong_count(&owner), 2);
        let copy = s.clone();
        assert_eq!(Arc::strong_count(&owner), 3);
        s.to_mut().push(9);
        assert!(!s.is_shared());
        assert_eq!(&*s, &[1, 2, 3, 9]);
        assert_eq!(&*copy, &[1, 2, 3]);
        drop((s, copy));
        assert_eq!(Arc::strong_count(&owner), 1);
    }
}
