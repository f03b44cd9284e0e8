//! A slice that several rayon tasks write through at indices the caller proves disjoint.

use std::marker::PhantomData;

/// Shared mutable access to a slice for parallel scatters whose index sets are disjoint by
/// construction (graph colouring of groups, or a permutation of particles).
pub(crate) struct DisjointSlice<'a, T> {
    ptr: *mut T,
    len: usize,
    _life: PhantomData<&'a mut [T]>,
}

// SAFETY: the wrapper only hands out `&mut T` through `get`, whose contract requires that no
// two threads ever access the same index concurrently; with that, sharing it across threads is
// as safe as sending disjoint `&mut T` to them, which needs `T: Send`.
unsafe impl<T: Send> Sync for DisjointSlice<'_, T> {}
// SAFETY: as above.
unsafe impl<T: Send> Send for DisjointSlice<'_, T> {}

impl<'a, T> DisjointSlice<'a, T> {
    pub(crate) fn new(slice: &'a mut [T]) -> Self {
        Self {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            _life: PhantomData,
        }
    }

    /// Hint the CPU to load element `i` (no-op off x86-64 or out of range).
    #[inline(always)]
    pub(crate) fn prefetch(&self, i: usize) {
        #[cfg(target_arch = "x86_64")]
        if i < self.len {
            // SAFETY: `i < len`, so the address is inside the slice; prefetching has no
            // architectural effect.
            unsafe {
                std::arch::x86_64::_mm_prefetch(
                    self.ptr.add(i).cast::<i8>().cast_const(),
                    std::arch::x86_64::_MM_HINT_T0,
                );
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = i;
    }

    /// # Safety
    /// No other reference to element `i` may be alive while the returned one is, in any thread.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn get(&self, i: usize) -> &mut T {
        debug_assert!(i < self.len);
        // SAFETY: `i < len` is guaranteed by callers (indices come from the stencil tables,
        // which only hold valid node or particle indices) and exclusivity by the contract.
        unsafe { &mut *self.ptr.add(i) }
    }
}
