//! Hessian assembly: triplets in, the upper triangle of the free-DOF matrix in compressed
//! sparse column form out, with the sparsity pattern compared to the previous one so the
//! symbolic factorisation can be reused.
//!
//! Convention: objectives push the symmetric Hessian's upper triangle, or both triangles (what
//! per-element block assembly produces naturally), duplicates summed; entries below the
//! diagonal are dropped here, entries touching a fixed DOF are dropped too (Dirichlet DOFs are
//! not unknowns).
//!
//! Assembly is a counting sort by column (linear in the number of triplets) followed by a small
//! sort-and-merge within each column, parallel over columns; no comparison sort over all
//! triplets. It remembers where each triplet landed: when the next build's triplets have the
//! same rows and columns in the same order (Newton iterations of one step with an unchanged
//! contact set), it only adds the values into place — bitwise the same result.

use rayon::prelude::*;

/// A growing list of `(row, col, value)` entries of a symmetric matrix (entries below the
/// diagonal are ignored by the assembly).
#[derive(Clone, Debug, Default)]
pub struct Triplets {
    pub(crate) rows: Vec<u32>,
    pub(crate) cols: Vec<u32>,
    pub(crate) vals: Vec<f64>,
}

impl Triplets {
    /// The entries `(row, col, value)`, in the order they were pushed (duplicates not merged).
    pub fn iter(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        self.rows
            .iter()
            .zip(&self.cols)
            .zip(&self.vals)
            .map(|((&r, &c), &v)| (r as usize, c as usize, v))
    }

    /// Remove all entries, keeping the memory.
    pub fn clear(&mut self) {
        self.rows.clear();
        self.cols.clear();
        self.vals.clear();
    }

    /// Add `value` at `(row, col)`.
    #[inline]
    pub fn push(&mut self, row: usize, col: usize, value: f64) {
        self.rows.push(row as u32);
        self.cols.push(col as u32);
        self.vals.push(value);
    }

    /// Add many entries at once.
    pub fn extend(&mut self, entries: impl IntoIterator<Item = (usize, usize, f64)>) {
        for (r, c, v) in entries {
            self.push(r, c, v);
        }
    }

    /// Reserve space for `n` more entries.
    pub fn reserve(&mut self, n: usize) {
        self.rows.reserve(n);
        self.cols.reserve(n);
        self.vals.reserve(n);
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.vals.len()
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.vals.is_empty()
    }

    /// Append `n` entries written by `fill(rows, cols, values)` into the new tail (given zeroed,
    /// `n` long each) — for writing many entries at once, e.g. in parallel over disjoint parts.
    pub fn append_with(&mut self, n: usize, fill: impl FnOnce(&mut [u32], &mut [u32], &mut [f64])) {
        let start = self.vals.len();
        self.rows.resize(start + n, 0);
        self.cols.resize(start + n, 0);
        self.vals.resize(start + n, 0.0);
        fill(
            &mut self.rows[start..],
            &mut self.cols[start..],
            &mut self.vals[start..],
        );
    }

    /// Append another list (e.g. one built by another thread).
    pub fn append(&mut self, other: &Triplets) {
        self.rows.extend_from_slice(&other.rows);
        self.cols.extend_from_slice(&other.cols);
        self.vals.extend_from_slice(&other.vals);
    }
}

/// Upper triangle of a symmetric matrix in CSC form, with the pattern of the previous build.
#[derive(Clone, Debug, Default)]
pub struct UpperCsc {
    pub(crate) n: usize,
    pub(crate) col_ptr: Vec<usize>,
    pub(crate) row_idx: Vec<usize>,
    pub(crate) values: Vec<f64>,
    // Scratch for the counting sort.
    count: Vec<usize>,
    tmp_rows: Vec<u32>,
    tmp_vals: Vec<f64>,
    prev_col_ptr: Vec<usize>,
    prev_row_idx: Vec<usize>,
    // The triplet structure of the last full build and where each triplet landed in `values`
    // (`u32::MAX`: dropped), so a build with the same structure (the Newton iterations of one
    // step, usually) only scatters values.
    last_rows: Vec<u32>,
    last_cols: Vec<u32>,
    last_free: Vec<u32>,
    tmp_idx: Vec<u32>,
    pos: Vec<u32>,
    // Scratch of `widen`: old value position → new one.
    remap: Vec<u32>,
    /// Builds that reused the previous structure (`scatter`) and full ones.
    pub(crate) reused: usize,
    pub(crate) full: usize,
    /// Identifies the sparsity pattern: a new process-wide number whenever it changes.
    pub(crate) pattern_id: u64,
}

/// Source of [`UpperCsc::pattern_id`] values (0 is never handed out).
static PATTERN_IDS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

fn new_pattern_id() -> u64 {
    PATTERN_IDS.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl UpperCsc {
    /// Number of rows (= columns).
    pub fn n(&self) -> usize {
        self.n
    }

    /// An `n × n` upper-triangular matrix of the pattern `col_ptr`, `row_idx` with every value
    /// 0 (to analyse a pattern kept from elsewhere, [`crate::Newton::restore_analysis`]). The
    /// pattern must be what [`UpperCsc::assemble`] builds: `col_ptr` of `n + 1` nondecreasing
    /// offsets from 0 to `row_idx.len()`, each column's rows strictly increasing, at most the
    /// column, and ending with the diagonal. Otherwise the first fault found, in words.
    pub fn from_pattern(n: usize, col_ptr: &[usize], row_idx: &[usize]) -> Result<Self, String> {
        if col_ptr.len() != n + 1 {
            return Err(format!(
                "{} column pointers for {n} columns (needs {})",
                col_ptr.len(),
                n + 1
            ));
        }
        if col_ptr[0] != 0 || col_ptr[n] != row_idx.len() {
            return Err(format!(
                "column pointers run from {} to {}, not from 0 to the {} row indices",
                col_ptr[0],
                col_ptr[n],
                row_idx.len()
            ));
        }
        for c in 0..n {
            let (a, b) = (col_ptr[c], col_ptr[c + 1]);
            if b <= a {
                return Err(format!("column {c} is empty (its diagonal is missing)"));
            }
            let rows = &row_idx[a..b];
            if rows.windows(2).any(|w| w[0] >= w[1]) || rows[rows.len() - 1] != c {
                return Err(format!(
                    "column {c}'s rows are not increasing up to its diagonal"
                ));
            }
        }
        Ok(Self {
            n,
            col_ptr: col_ptr.to_vec(),
            row_idx: row_idx.to_vec(),
            values: vec![0.0; row_idx.len()],
            pattern_id: new_pattern_id(),
            ..Self::default()
        })
    }

    /// A number identifying the current sparsity pattern: it changes (process-wide unique)
    /// whenever a build or [`UpperCsc::widen`] changes the pattern, so derived structures can
    /// be kept while it stays the same. 0 before the first build.
    pub fn pattern_id(&self) -> u64 {
        self.pattern_id
    }

    /// Stored entries.
    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// Column pointers.
    pub fn col_ptr(&self) -> &[usize] {
        &self.col_ptr
    }

    /// Row indices.
    pub fn row_idx(&self) -> &[usize] {
        &self.row_idx
    }

    /// Values.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Mutable values (e.g. to shift the diagonal).
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }

    /// Index of the diagonal entry of column `j` in `values` (the last entry of the column, if
    /// present).
    pub fn diagonal_index(&self, j: usize) -> Option<usize> {
        let end = self.col_ptr[j + 1];
        (end > self.col_ptr[j] && self.row_idx[end - 1] == j).then_some(end - 1)
    }

    /// Build from triplets over all DOFs, keeping free DOFs only (`free[dof]` is the free index
    /// or `u32::MAX`) and the upper triangle. Returns whether the sparsity pattern changed since
    /// the previous build. Every diagonal entry of a free DOF is present (zero if not given), so
    /// that diagonal shifts always have a slot.
    pub fn assemble(&mut self, t: &Triplets, free: &[u32], n_free: usize) -> bool {
        if n_free == self.n
            && !self.pos.is_empty()
            && t.rows == self.last_rows
            && t.cols == self.last_cols
            && free == self.last_free.as_slice()
        {
            // Same triplets at the same places: the pattern is the one built last time. The
            // sums run in the same order as the merge (triplet order), so the values are
            // bitwise those of a full build.
            self.values.iter_mut().for_each(|v| *v = 0.0);
            for (k, &at) in self.pos.iter().enumerate() {
                if at != u32::MAX {
                    self.values[at as usize] += t.vals[k];
                }
            }
            self.reused += 1;
            return false;
        }
        if n_free == self.n
            && !self.pos.is_empty()
            && free == self.last_free.as_slice()
            && self.splice(t, free)
        {
            return false;
        }
        self.full += 1;
        self.pattern_id = new_pattern_id();
        std::mem::swap(&mut self.prev_col_ptr, &mut self.col_ptr);
        std::mem::swap(&mut self.prev_row_idx, &mut self.row_idx);
        let n = n_free;
        self.n = n;
        // 1. Count per column (upper part of free × free), plus one diagonal slot each.
        self.count.clear();
        self.count.resize(n + 1, 0);
        for c in 0..n {
            self.count[c + 1] = 1;
        }
        for k in 0..t.vals.len() {
            let (fr, fc) = (free[t.rows[k] as usize], free[t.cols[k] as usize]);
            if fr != u32::MAX && fc != u32::MAX && fr <= fc {
                self.count[fc as usize + 1] += 1;
            }
        }
        for c in 0..n {
            self.count[c + 1] += self.count[c];
        }
        let total = self.count[n];
        self.tmp_rows.clear();
        self.tmp_rows.resize(total, 0);
        self.tmp_vals.clear();
        self.tmp_vals.resize(total, 0.0);
        // Positions are tracked in u32: a build too large for that is always done in full.
        let track = total < u32::MAX as usize && t.vals.len() < u32::MAX as usize;
        self.tmp_idx.clear();
        self.tmp_idx.resize(total, u32::MAX);
        // Diagonal slots first.
        let mut fill: Vec<usize> = self.count[..n].to_vec();
        for c in 0..n {
            self.tmp_rows[fill[c]] = c as u32;
            fill[c] += 1;
        }
        for k in 0..t.vals.len() {
            let (fr, fc) = (free[t.rows[k] as usize], free[t.cols[k] as usize]);
            if fr != u32::MAX && fc != u32::MAX && fr <= fc {
                let at = fill[fc as usize];
                self.tmp_rows[at] = fr;
                self.tmp_vals[at] = t.vals[k];
                if track {
                    self.tmp_idx[at] = k as u32;
                }
                fill[fc as usize] += 1;
            }
        }
        // Where each triplet lands, column-local for now (`u32::MAX`: dropped).
        self.pos.clear();
        if track {
            self.pos.resize(t.vals.len(), u32::MAX);
        }
        // 2. Sort and merge within each column (parallel; columns are independent).
        let count = &self.count;
        let mut merged_len = vec![0usize; n];
        {
            let rows = SendPtr(self.tmp_rows.as_mut_ptr());
            let vals = SendPtr(self.tmp_vals.as_mut_ptr());
            let idx = SendPtr(self.tmp_idx.as_mut_ptr());
            let pos = SendPtr(self.pos.as_mut_ptr());
            merged_len
                .par_iter_mut()
                .enumerate()
                .with_min_len(256)
                .for_each(|(c, len)| {
                    let (a, b) = (count[c], count[c + 1]);
                    // SAFETY: column ranges [count[c], count[c+1]) are disjoint, so each task has
                    // exclusive access to its own sub-slices.
                    let (r, v, ix) = unsafe {
                        (
                            std::slice::from_raw_parts_mut(rows.get().add(a), b - a),
                            std::slice::from_raw_parts_mut(vals.get().add(a), b - a),
                            std::slice::from_raw_parts_mut(idx.get().add(a), b - a),
                        )
                    };
                    *len = sort_merge(r, v, ix, |k, local| {
                        // SAFETY: each triplet index appears in exactly one column, so no two
                        // tasks write the same entry of `pos`.
                        unsafe { *pos.get().add(k as usize) = local as u32 };
                    });
                });
        }
        // 3. Compact into the output arrays.
        self.col_ptr.clear();
        self.col_ptr.push(0);
        let nnz: usize = merged_len.iter().sum();
        self.row_idx.clear();
        self.row_idx.reserve(nnz);
        self.values.clear();
        self.values.reserve(nnz);
        for c in 0..n {
            let a = count[c];
            let m = merged_len[c];
            self.row_idx
                .extend(self.tmp_rows[a..a + m].iter().map(|&r| r as usize));
            self.values.extend_from_slice(&self.tmp_vals[a..a + m]);
            self.col_ptr.push(self.row_idx.len());
        }
        for k in 0..self.pos.len() {
            if self.pos[k] != u32::MAX {
                let fc = free[t.cols[k] as usize] as usize;
                self.pos[k] += self.col_ptr[fc] as u32;
            }
        }
        self.last_rows.clone_from(&t.rows);
        self.last_cols.clone_from(&t.cols);
        self.last_free.clear();
        self.last_free.extend_from_slice(free);
        self.col_ptr != self.prev_col_ptr || self.row_idx != self.prev_row_idx
    }
}

impl UpperCsc {
    /// A build whose triplets differ from the last full build's only in a middle stretch (the
    /// same leading and trailing triplets — e.g. a Hessian whose contact terms changed between
    /// the elastic blocks), and whose every new triplet lands on an entry of the current
    /// pattern: the positions of the middle are looked up (binary search in their column), the
    /// rest kept, and the values scattered in triplet order — so each entry sums its triplets in
    /// the order a full build would, and entries no triplet reaches any more stay as explicit
    /// zeros. Returns `false` (nothing changed) if some new triplet is not in the pattern.
    fn splice(&mut self, t: &Triplets, free: &[u32]) -> bool {
        let (old_len, new_len) = (self.last_rows.len(), t.rows.len());
        if new_len >= u32::MAX as usize || self.pos.len() != old_len {
            return false;
        }
        let same = |k_new: usize, k_old: usize| {
            t.rows[k_new] == self.last_rows[k_old] && t.cols[k_new] == self.last_cols[k_old]
        };
        let short = old_len.min(new_len);
        let mut pre = 0;
        while pre < short && same(pre, pre) {
            pre += 1;
        }
        let mut suf = 0;
        while suf < short - pre && same(new_len - 1 - suf, old_len - 1 - suf) {
            suf += 1;
        }
        self.remap.clear();
        for k in pre..new_len - suf {
            let (fr, fc) = (free[t.rows[k] as usize], free[t.cols[k] as usize]);
            if fr == u32::MAX || fc == u32::MAX || fr > fc {
                self.remap.push(u32::MAX);
                continue;
            }
            let (a, b) = (self.col_ptr[fc as usize], self.col_ptr[fc as usize + 1]);
            match self.row_idx[a..b].binary_search(&(fr as usize)) {
                Ok(i) => self.remap.push((a + i) as u32),
                Err(_) => return false,
            }
        }
        // pos = old pos[..pre] ++ middle ++ old pos[old_len − suf..].
        let (tail, m) = (old_len - suf, self.remap.len());
        if new_len > old_len {
            self.pos.resize(new_len, u32::MAX);
        }
        self.pos.copy_within(tail..tail + suf, pre + m);
        self.pos.truncate(new_len);
        self.pos[pre..pre + self.remap.len()].copy_from_slice(&self.remap);
        self.last_rows.clone_from(&t.rows);
        self.last_cols.clone_from(&t.cols);
        self.values.iter_mut().for_each(|v| *v = 0.0);
        for (k, &at) in self.pos.iter().enumerate() {
            if at != u32::MAX {
                self.values[at as usize] += t.vals[k];
            }
        }
        self.reused += 1;
        true
    }

    /// Rewrite this matrix into a wider pattern `base` (upper CSC of the same size, rows sorted
    /// in each column, every diagonal present): the union of both patterns, the new entries
    /// explicit zeros. Returns whether this matrix's pattern was already contained in `base` —
    /// the result's pattern is then exactly `base`. With `union == false` a pattern not
    /// contained in `base` is left as it is. The values keep their bits, and a later
    /// [`UpperCsc::assemble`] with the same triplet structure scatters into the widened layout.
    ///
    /// This lets a factorisation analysed for `base` serve every matrix whose pattern it
    /// contains (a contact pair that appears in one Newton iteration and not the next), and an
    /// analysis cover the union of the patterns seen so far.
    pub fn widen(&mut self, base_col_ptr: &[usize], base_row_idx: &[usize], union: bool) -> bool {
        let n = self.n;
        if base_col_ptr.len() != n + 1 || self.col_ptr.len() != n + 1 {
            return false;
        }
        // Pass 1: containment, and the union's size.
        let mut contained = true;
        let mut union_nnz = 0;
        for c in 0..n {
            let (mine, base) = (
                &self.row_idx[self.col_ptr[c]..self.col_ptr[c + 1]],
                &base_row_idx[base_col_ptr[c]..base_col_ptr[c + 1]],
            );
            let (mut i, mut j) = (0, 0);
            while i < mine.len() || j < base.len() {
                if j == base.len() || (i < mine.len() && mine[i] < base[j]) {
                    contained = false;
                    i += 1;
                } else if i == mine.len() || base[j] < mine[i] {
                    j += 1;
                } else {
                    i += 1;
                    j += 1;
                }
                union_nnz += 1;
            }
        }
        if (!contained && !union) || union_nnz >= u32::MAX as usize {
            return false;
        }
        if union_nnz == self.values.len() {
            // Same pattern already.
            return contained;
        }
        // Pass 2: merge into the union; remember where each old value went.
        self.remap.clear();
        self.remap.resize(self.values.len(), 0);
        let mut rows = std::mem::take(&mut self.tmp_rows);
        let mut vals = std::mem::take(&mut self.tmp_vals);
        rows.clear();
        vals.clear();
        rows.reserve(union_nnz);
        vals.reserve(union_nnz);
        self.count.clear();
        self.count.push(0);
        for c in 0..n {
            let (a, b) = (self.col_ptr[c], self.col_ptr[c + 1]);
            let base = &base_row_idx[base_col_ptr[c]..base_col_ptr[c + 1]];
            let (mut i, mut j) = (a, 0);
            while i < b || j < base.len() {
                if j == base.len() || (i < b && self.row_idx[i] < base[j]) {
                    self.remap[i] = rows.len() as u32;
                    rows.push(self.row_idx[i] as u32);
                    vals.push(self.values[i]);
                    i += 1;
                } else if i == b || base[j] < self.row_idx[i] {
                    rows.push(base[j] as u32);
                    vals.push(0.0);
                    j += 1;
                } else {
                    self.remap[i] = rows.len() as u32;
                    rows.push(self.row_idx[i] as u32);
                    vals.push(self.values[i]);
                    i += 1;
                    j += 1;
                }
            }
            self.count.push(rows.len());
        }
        self.col_ptr.clear();
        self.col_ptr.extend_from_slice(&self.count);
        self.row_idx.clear();
        self.row_idx.extend(rows.iter().map(|&r| r as usize));
        self.values.clear();
        self.values.extend_from_slice(&vals);
        self.pattern_id = new_pattern_id();
        for at in self.pos.iter_mut() {
            if *at != u32::MAX {
                *at = self.remap[*at as usize];
            }
        }
        self.tmp_rows = rows;
        self.tmp_vals = vals;
        contained
    }
}

/// Sort `(rows, vals, idx)` by row (stably) and merge duplicates (summing values in their
/// original order); `placed(idx, local)` is told the merged position of every entry whose
/// `idx` is not `u32::MAX`. Returns the merged length.
fn sort_merge(
    rows: &mut [u32],
    vals: &mut [f64],
    idx: &mut [u32],
    mut placed: impl FnMut(u32, usize),
) -> usize {
    let n = rows.len();
    if n == 0 {
        return 0;
    }
    // Insertion sort: columns are short and often nearly sorted.
    for i in 1..n {
        let (r, v, k) = (rows[i], vals[i], idx[i]);
        let mut j = i;
        while j > 0 && rows[j - 1] > r {
            rows[j] = rows[j - 1];
            vals[j] = vals[j - 1];
            idx[j] = idx[j - 1];
            j -= 1;
        }
        rows[j] = r;
        vals[j] = v;
        idx[j] = k;
    }
    let mut w = 0;
    if idx[0] != u32::MAX {
        placed(idx[0], 0);
    }
    for i in 1..n {
        if rows[i] == rows[w] {
            vals[w] += vals[i];
        } else {
            w += 1;
            rows[w] = rows[i];
            vals[w] = vals[i];
        }
        if idx[i] != u32::MAX {
            placed(idx[i], w);
        }
    }
    w + 1
}

#[derive(Clone, Copy)]
struct SendPtr<T>(*mut T);
impl<T> SendPtr<T> {
    fn get(self) -> *mut T {
        self.0
    }
}
// SAFETY: used only to hand disjoint sub-slices to rayon tasks (see `assemble`).
unsafe impl<T> Send for SendPtr<T> {}
// SAFETY: as above.
unsafe impl<T> Sync for SendPtr<T> {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assembles_upper_free_part_and_detects_pattern_changes() {
        let mut t = Triplets::default();
        // 3 DOFs, DOF 1 fixed; full symmetric input with duplicates.
        for &(r, c, v) in &[
            (0, 0, 1.0),
            (0, 2, 2.0),
            (2, 0, 2.0),
            (2, 2, 3.0),
            (0, 0, 0.5),
            (1, 1, 9.0),
            (0, 1, 7.0),
            (1, 0, 7.0),
        ] {
            t.push(r, c, v);
        }
        let free = [0u32, u32::MAX, 1];
        let mut a = UpperCsc::default();
        assert!(a.assemble(&t, &free, 2));
        assert_eq!(a.col_ptr(), &[0, 1, 3]);
        assert_eq!(a.row_idx(), &[0, 0, 1]);
        assert_eq!(a.values(), &[1.5, 2.0, 3.0]);
        assert_eq!(a.diagonal_index(1), Some(2));
        // Same pattern, new values.
        t.vals.iter_mut().for_each(|v| *v *= 2.0);
        assert!(!a.assemble(&t, &free, 2));
        assert_eq!(a.values(), &[3.0, 4.0, 6.0]);
        // Remove the coupling: the remaining triplets lie in the pattern, which is kept (the
        // coupling an explicit zero); diagonals stay.
        t.clear();
        t.push(0, 0, 1.0);
        assert!(!a.assemble(&t, &free, 2));
        assert_eq!(a.row_idx(), &[0, 0, 1]);
        assert_eq!(a.values(), &[1.0, 0.0, 0.0]);
        // A new free map: built in full, the pattern changes.
        assert!(a.assemble(&t, &[0, 1, u32::MAX], 2));
        assert_eq!(a.row_idx(), &[0, 1]);
        assert_eq!(a.values(), &[1.0, 0.0]);
    }

    /// A build with the previous build's triplet structure only scatters values, and gives
    /// bitwise the values of a fresh full build (random structure with duplicates, fixed DOFs
    /// and lower-triangle entries); a changed structure builds in full again.
    #[test]
    fn reused_structure_gives_the_same_values_as_a_full_build() {
        let mut seed = 12345u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let n = 40;
        let free: Vec<u32> = (0..n as u32)
            .scan(0u32, |next, d| {
                Some(if d % 7 == 3 {
                    u32::MAX
                } else {
                    *next += 1;
                    *next - 1
                })
            })
            .collect();
        let nf = free.iter().filter(|&&f| f != u32::MAX).count();
        let mut t = Triplets::default();
        for _ in 0..600 {
            // Banded (|r − c| ≤ 5), so the coupling of DOFs 0 and n − 1 below is new.
            let r = (rnd() % n) as usize;
            let c = (r + (rnd() % 6) as usize).min(n as usize - 1);
            let v = (rnd() % 1000) as f64 / 7.0 - 60.0;
            t.push(r, c, v);
            t.push(c, r, v);
        }
        let mut a = UpperCsc::default();
        assert!(a.assemble(&t, &free, nf));
        for (k, v) in t.vals.iter_mut().enumerate() {
            *v = (*v * 1.37 + k as f64 * 0.01).sin() * 1e3;
        }
        assert!(!a.assemble(&t, &free, nf));
        assert_eq!((a.full, a.reused), (1, 1));
        let mut fresh = UpperCsc::default();
        fresh.assemble(&t, &free, nf);
        assert_eq!(a.col_ptr(), fresh.col_ptr());
        assert_eq!(a.row_idx(), fresh.row_idx());
        let bits = |x: &[f64]| x.iter().map(|v| (v + 0.0).to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(a.values()), bits(fresh.values()));
        // More entries, and the pattern reported as changed exactly when it differs from the
        // previous one: a duplicate of an existing entry is spliced in (no), a new coupling
        // between the first and last free DOF is built in full (yes).
        let (r0, c0) = (t.rows[0] as usize, t.cols[0] as usize);
        for (r, c, new_entry) in [(r0, c0, false), (0, n as usize - 1, true)] {
            let before = (a.col_ptr().to_vec(), a.row_idx().to_vec());
            t.push(r, c, 1.0);
            t.push(c, r, 1.0);
            let changed = a.assemble(&t, &free, nf);
            let mut fresh = UpperCsc::default();
            fresh.assemble(&t, &free, nf);
            assert_eq!(changed, new_entry);
            assert_eq!(
                changed,
                (before.0, before.1) != (fresh.col_ptr().to_vec(), fresh.row_idx().to_vec())
            );
            assert_eq!(bits(a.values()), bits(fresh.values()));
        }
        assert_eq!((a.full, a.reused), (2, 2));
    }

    fn dense(a: &UpperCsc) -> Vec<Vec<f64>> {
        let mut d = vec![vec![0.0; a.n()]; a.n()];
        for c in 0..a.n() {
            for k in a.col_ptr()[c]..a.col_ptr()[c + 1] {
                d[a.row_idx()[k]][c] += a.values()[k];
            }
        }
        d
    }

    fn pattern(a: &UpperCsc) -> Vec<(usize, usize)> {
        (0..a.n())
            .flat_map(|c| (a.col_ptr()[c]..a.col_ptr()[c + 1]).map(move |k| (c, k)))
            .map(|(c, k)| (a.row_idx()[k], c))
            .collect()
    }

    /// `widen`: a contained pattern becomes exactly the base (new entries zero, values and
    /// later structure-reusing builds unchanged); a pattern not contained is left alone, or
    /// merged into the union.
    #[test]
    fn widening_into_a_containing_pattern_keeps_the_matrix_and_later_builds() {
        let mut seed = 987u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let n = 30usize;
        let free: Vec<u32> = (0..n as u32).collect();
        let mut entries = Vec::new();
        for _ in 0..200 {
            let r = (rnd() % n as u64) as usize;
            let c = (r + (rnd() % 8) as usize).min(n - 1);
            entries.push((r, c, (rnd() % 1000) as f64 / 3.0 - 100.0));
        }
        let build = |es: &[(usize, usize, f64)]| {
            let mut t = Triplets::default();
            for &(r, c, v) in es {
                t.push(r, c, v);
                t.push(c, r, v);
            }
            t
        };
        // Base: all entries plus a far coupling; the matrix: a subset of the entries.
        let mut all = entries.clone();
        all.push((0, n - 1, 1.0));
        let mut base = UpperCsc::default();
        base.assemble(&build(&all), &free, n);
        let subset: Vec<_> = entries.iter().copied().step_by(3).collect();
        let mut t = build(&subset);
        let mut a = UpperCsc::default();
        a.assemble(&t, &free, n);
        let before = dense(&a);
        assert_ne!(pattern(&a), pattern(&base));
        assert!(a.widen(base.col_ptr(), base.row_idx(), false));
        assert_eq!(pattern(&a), pattern(&base));
        assert_eq!(dense(&a), before, "widening changes no value");
        // A build with the same triplet structure scatters into the widened layout.
        for (k, v) in t.vals.iter_mut().enumerate() {
            *v = (k as f64 * 0.37).cos() * 10.0;
        }
        assert!(!a.assemble(&t, &free, n), "same pattern as the widened one");
        assert_eq!(pattern(&a), pattern(&base));
        let mut fresh = UpperCsc::default();
        fresh.assemble(&t, &free, n);
        assert_eq!(dense(&a), dense(&fresh));

        // Not contained: left alone without `union`, merged with it.
        let mut extra = subset.clone();
        extra.push((1, n - 2, 5.0));
        let t2 = build(&extra);
        let mut b = UpperCsc::default();
        b.assemble(&t2, &free, n);
        let (pat, val) = (pattern(&b), dense(&b));
        assert!(!b.widen(base.col_ptr(), base.row_idx(), false));
        assert_eq!((pattern(&b), dense(&b)), (pat.clone(), val.clone()));
        assert!(!b.widen(base.col_ptr(), base.row_idx(), true));
        let mut union: Vec<_> = pat.iter().chain(pattern(&base).iter()).copied().collect();
        union.sort_by_key(|&(r, c)| (c, r));
        union.dedup();
        assert_eq!(pattern(&b), union);
        assert_eq!(dense(&b), val);
        // The union contains the base: the base widens into it exactly.
        let mut base2 = base.clone();
        assert!(base2.widen(b.col_ptr(), b.row_idx(), false));
        assert_eq!(pattern(&base2), union);
        assert_eq!(dense(&base2), dense(&base));
        // A base of another size is never containing.
        let mut small = UpperCsc::default();
        small.assemble(&build(&[(0, 1, 1.0)]), &[0, 1], 2);
        assert!(!a.widen(small.col_ptr(), small.row_idx(), true));
    }

    /// Triplets that keep their leading and trailing runs and change in between (a contact set
    /// that changes inside a Hessian): entries of the current pattern are found and the values
    /// scattered, bitwise equal to a fresh build where both have entries, explicit zeros where
    /// no triplet lands any more, the pattern (and its id) kept; a middle with an entry outside
    /// the pattern, or a fixed DOF's, is built in full. Longer, shorter and empty middles.
    #[test]
    fn changed_middle_triplets_are_spliced_into_the_pattern() {
        let mut seed = 4242u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let n = 40usize;
        let free: Vec<u32> = (0..n as u32).collect();
        let mut val = move || (rnd() % 1000) as f64 / 7.0 - 60.0;
        let push_sym = |t: &mut Triplets, r: usize, c: usize, v: f64| {
            t.push(r, c, v);
            t.push(c, r, v);
        };
        // Prefix: a band; middle: couplings (i, i + 5); suffix: a band again and the diagonal.
        let make = |middle: &[(usize, usize)], val: &mut dyn FnMut() -> f64| {
            let mut t = Triplets::default();
            for i in 0..n - 1 {
                push_sym(&mut t, i, i + 1, val());
            }
            for &(r, c) in middle {
                push_sym(&mut t, r, c, val());
            }
            for i in 0..n - 2 {
                push_sym(&mut t, i, i + 2, val());
            }
            for i in 0..n {
                t.push(i, i, 100.0 + val());
            }
            t
        };
        let full: Vec<(usize, usize)> = (0..n - 5).map(|i| (i, i + 5)).collect();
        let mut a = UpperCsc::default();
        a.assemble(&make(&full, &mut val), &free, n);
        let (pat, id) = (pattern(&a), a.pattern_id());
        for middle in [
            full.iter().copied().step_by(2).collect::<Vec<_>>(),
            vec![],
            full.iter()
                .copied()
                .chain(full.iter().copied().take(7))
                .collect(),
            vec![(3, 8), (3, 8), (12, 17)],
        ] {
            let t = make(&middle, &mut val);
            let full_builds = a.full;
            assert!(!a.assemble(&t, &free, n), "pattern unchanged");
            assert_eq!(a.full, full_builds, "spliced, not rebuilt");
            assert_eq!((pattern(&a), a.pattern_id()), (pat.clone(), id));
            let mut fresh = UpperCsc::default();
            fresh.assemble(&t, &free, n);
            assert_eq!(dense(&a), dense(&fresh), "middle {middle:?}");
            // Bitwise on the fresh build's entries, zeros elsewhere.
            for (k, &(r, c)) in pattern(&a).iter().enumerate() {
                let f = pattern(&fresh).iter().position(|&e| e == (r, c));
                let want = f.map_or(0.0, |j| fresh.values()[j]);
                assert_eq!(a.values()[k].to_bits(), want.to_bits(), "({r}, {c})");
            }
        }
        // An entry outside the pattern: a full build, equal to a fresh one.
        let t = make(&[(0, 30)], &mut val);
        let full_builds = a.full;
        assert!(a.assemble(&t, &free, n), "pattern changed");
        assert_eq!(a.full, full_builds + 1);
        let mut fresh = UpperCsc::default();
        fresh.assemble(&t, &free, n);
        assert_eq!((pattern(&a), dense(&a)), (pattern(&fresh), dense(&fresh)));
        assert_ne!(a.pattern_id(), id);
        // Another free map: never spliced.
        let mut fixed = free.clone();
        fixed[n - 1] = u32::MAX;
        let full_builds = a.full;
        a.assemble(&t, &fixed, n - 1);
        assert_eq!(a.full, full_builds + 1);
    }
}
