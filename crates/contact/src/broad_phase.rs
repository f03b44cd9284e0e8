//! Broad phase: which boundary facets each particle must be tested against.
//!
//! A uniform spatial hash over facet bounding boxes (inflated by the query distance), built once
//! per query: facets are binned into the cells their box overlaps (a counting sort by cell, the
//! cells numbered densely over the facets' bounding box, or through a hash map when that box is
//! mostly empty), and each particle looks up the cells its own box overlaps, taking each facet
//! from the lowest cell it shares with the particle only (so no duplicates to remove). Cost
//! grows linearly with the number of particles and facets (not their product); memory with the
//! occupied cells.
//! Written here rather than taken from parry because one generic source serves 2D and 3D
//! (parry splits them into two crates with different math types).
//!
//! * [`candidates_within`] — facets whose box, inflated by `dist`, contains the particle
//!   (`dist = d̂` gives every pair the barrier can see);
//! * [`candidates_swept`] — facets whose swept box (start and end of a step) overlaps the
//!   particle's swept box inflated by `dist` (every pair that can come within `dist` during a
//!   linear step; CCD and the line search use it).
//!
//! Results are [`Candidates`]: a list of facet indices per particle, sorted, without repeats.

use nalgebra::SVector;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

/// Facet indices per particle (CSR).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Candidates {
    start: Vec<u32>,
    facets: Vec<u32>,
}

impl Candidates {
    /// Candidate facets of particle `q`.
    #[inline]
    pub fn of(&self, q: usize) -> &[u32] {
        &self.facets[self.start[q] as usize..self.start[q + 1] as usize]
    }

    /// Number of particles.
    pub fn num_particles(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// Total number of (particle, facet) pairs.
    pub fn num_pairs(&self) -> usize {
        self.facets.len()
    }

    /// From explicit lists (tests, small problems).
    pub fn from_lists(lists: &[Vec<u32>]) -> Self {
        let mut start = vec![0u32];
        let mut facets = Vec::new();
        for l in lists {
            let mut l = l.clone();
            l.sort_unstable();
            l.dedup();
            facets.extend_from_slice(&l);
            start.push(facets.len() as u32);
        }
        Self { start, facets }
    }
}

#[derive(Clone, Copy)]
struct Aabb<const D: usize> {
    lo: SVector<f64, D>,
    hi: SVector<f64, D>,
}

impl<const D: usize> Aabb<D> {
    fn of(points: &[&SVector<f64, D>]) -> Self {
        let mut lo = *points[0];
        let mut hi = *points[0];
        for p in &points[1..] {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        Self { lo, hi }
    }
    fn inflate(mut self, r: f64) -> Self {
        self.lo.add_scalar_mut(-r);
        self.hi.add_scalar_mut(r);
        self
    }
    fn overlaps(&self, o: &Self) -> bool {
        (0..D).all(|a| self.lo[a] <= o.hi[a] && o.lo[a] <= self.hi[a])
    }
}

/// Facets that may come within `dist` of each particle (now).
pub fn candidates_within<const D: usize>(
    particles: &[SVector<f64, D>],
    boundary: &[SVector<f64, D>],
    facets: &[[u32; 3]],
    dist: f64,
    out: &mut Candidates,
) {
    let pboxes: Vec<Aabb<D>> = particles
        .iter()
        .map(|p| Aabb { lo: *p, hi: *p }.inflate(dist))
        .collect();
    let fboxes: Vec<Aabb<D>> = facets
        .iter()
        .map(|f| facet_box(f, boundary, None))
        .collect();
    query(&pboxes, &fboxes, out);
}

/// Facets that may come within `dist` of each particle during a linear step from `particles0`
/// to `particles1` while the boundary moves from `boundary0` to `boundary1`.
pub fn candidates_swept<const D: usize>(
    particles0: &[SVector<f64, D>],
    particles1: &[SVector<f64, D>],
    boundary0: &[SVector<f64, D>],
    boundary1: &[SVector<f64, D>],
    facets: &[[u32; 3]],
    dist: f64,
    out: &mut Candidates,
) {
    let pboxes: Vec<Aabb<D>> = particles0
        .iter()
        .zip(particles1)
        .map(|(a, b)| Aabb::of(&[a, b]).inflate(dist))
        .collect();
    let fboxes: Vec<Aabb<D>> = facets
        .iter()
        .map(|f| facet_box(f, boundary0, Some(boundary1)))
        .collect();
    query(&pboxes, &fboxes, out);
}

/// The box of a facet's `D` vertices in `x0` (and `x1`, if given).
#[inline]
fn facet_box<const D: usize>(
    f: &[u32; 3],
    x0: &[SVector<f64, D>],
    x1: Option<&[SVector<f64, D>]>,
) -> Aabb<D> {
    let mut b = Aabb {
        lo: x0[f[0] as usize],
        hi: x0[f[0] as usize],
    };
    for &v in &f[1..D] {
        b.lo = b.lo.inf(&x0[v as usize]);
        b.hi = b.hi.sup(&x0[v as usize]);
    }
    if let Some(x1) = x1 {
        for &v in &f[..D] {
            b.lo = b.lo.inf(&x1[v as usize]);
            b.hi = b.hi.sup(&x1[v as usize]);
        }
    }
    b
}

/// Cell budget per query box before falling back to a scan of all facets.
const MAX_CELLS_PER_QUERY: usize = 4096;

/// Largest dense cell table (entries) before the cells are numbered through a hash map instead.
const MAX_DENSE_CELLS: usize = 1 << 22;

/// Facets binned into the cells their boxes overlap (CSR by cell, counting sort: no comparison
/// sort). Cells are numbered densely over the facets' bounding box when that box has few enough
/// cells (`MAX_DENSE_CELLS`, and at most 8 per binned entry), else through a hash map.
struct Bins<const D: usize> {
    inv: f64,
    /// Cell range of all facets.
    glo: [i64; D],
    ghi: [i64; D],
    /// Linear-index strides of the dense table (unused when `sparse` is set).
    stride: [usize; D],
    sparse: Option<FxHashMap<[i64; D], u32>>,
    /// `start[c]..start[c + 1]` indexes `facets` for cell number `c`.
    start: Vec<u32>,
    facets: Vec<u32>,
    /// Each binned facet's lowest cell (`lo[f]`), for reporting a facet once per query.
    flo: Vec<[i64; D]>,
    /// Facets too large to bin, scanned by every query.
    big: Vec<u32>,
}

impl<const D: usize> Bins<D> {
    fn range(&self, b: &Aabb<D>) -> ([i64; D], [i64; D]) {
        (
            std::array::from_fn(|a| (b.lo[a] * self.inv).floor() as i64),
            std::array::from_fn(|a| (b.hi[a] * self.inv).floor() as i64),
        )
    }

    fn cell_number(&self, c: &[i64; D]) -> Option<usize> {
        match &self.sparse {
            Some(map) => map.get(c).map(|&k| k as usize),
            None => Some(
                (0..D)
                    .map(|a| (c[a] - self.glo[a]) as usize * self.stride[a])
                    .sum(),
            ),
        }
    }

    fn build(fboxes: &[Aabb<D>], all: &Aabb<D>, cell: f64) -> Self {
        let inv = 1.0 / cell;
        let mut bins = Self {
            inv,
            glo: [0; D],
            ghi: [0; D],
            stride: [0; D],
            sparse: None,
            start: Vec::new(),
            facets: Vec::new(),
            flo: vec![[0; D]; fboxes.len()],
            big: Vec::new(),
        };
        (bins.glo, bins.ghi) = bins.range(all);
        // Count the binned entries, and set the big facets aside.
        let mut entries = 0usize;
        let mut binned = vec![true; fboxes.len()];
        for (f, b) in fboxes.iter().enumerate() {
            let (lo, hi) = bins.range(b);
            let n = ncells(&lo, &hi);
            if n > MAX_CELLS_PER_QUERY {
                bins.big.push(f as u32);
                binned[f] = false;
            } else {
                entries += n;
            }
            bins.flo[f] = lo;
        }
        let dense = (0..D)
            .map(|a| span(bins.glo[a], bins.ghi[a]))
            .try_fold(1usize, |x, y| x.checked_mul(y))
            .filter(|&n| n <= MAX_DENSE_CELLS && n <= 8 * entries.max(1024));
        // Each binned entry's cell number, in facet order.
        let mut entry: Vec<(u32, u32)> = Vec::with_capacity(entries);
        let ncell = match dense {
            Some(n) => {
                let mut s = 1;
                for a in 0..D {
                    bins.stride[a] = s;
                    s *= (bins.ghi[a] - bins.glo[a] + 1) as usize;
                }
                for (f, b) in fboxes.iter().enumerate() {
                    if binned[f] {
                        let (lo, hi) = bins.range(b);
                        for_each_cell(&lo, &hi, |c| {
                            let k: usize = (0..D)
                                .map(|a| (c[a] - bins.glo[a]) as usize * bins.stride[a])
                                .sum();
                            entry.push((k as u32, f as u32));
                        });
                    }
                }
                n
            }
            None => {
                let mut map: FxHashMap<[i64; D], u32> = FxHashMap::default();
                for (f, b) in fboxes.iter().enumerate() {
                    if binned[f] {
                        let (lo, hi) = bins.range(b);
                        for_each_cell(&lo, &hi, |c| {
                            let k = map.len() as u32;
                            let k = *map.entry(c).or_insert(k);
                            entry.push((k, f as u32));
                        });
                    }
                }
                let n = map.len();
                bins.sparse = Some(map);
                n
            }
        };
        // Counting sort of the entries by cell.
        let mut start = vec![0u32; ncell + 1];
        for &(k, _) in &entry {
            start[k as usize + 1] += 1;
        }
        for k in 0..ncell {
            start[k + 1] += start[k];
        }
        let mut next = start.clone();
        let mut facets = vec![0u32; entry.len()];
        for &(k, f) in &entry {
            facets[next[k as usize] as usize] = f;
            next[k as usize] += 1;
        }
        bins.start = start;
        bins.facets = facets;
        bins
    }
}

fn ncells<const D: usize>(lo: &[i64; D], hi: &[i64; D]) -> usize {
    (0..D)
        .map(|a| span(lo[a], hi[a]))
        .fold(1usize, |x, y| x.saturating_mul(y))
}

/// Number of cells in `lo..=hi` (saturating: infinite or huge coordinates floor to `i64::MIN` /
/// `i64::MAX`, and such a box must count as huge, not overflow).
fn span(lo: i64, hi: i64) -> usize {
    if hi < lo {
        0
    } else {
        usize::try_from(hi.abs_diff(lo)).map_or(usize::MAX, |d| d.saturating_add(1))
    }
}

fn query<const D: usize>(pboxes: &[Aabb<D>], fboxes: &[Aabb<D>], out: &mut Candidates) {
    out.start.clear();
    out.facets.clear();
    out.start.push(0);
    if fboxes.is_empty() || pboxes.is_empty() {
        out.start.resize(pboxes.len() + 1, 0);
        return;
    }
    // Cell size: the mean facet box extent, but at least the mean particle box extent, so that
    // a typical query touches a few cells.
    let extent = |b: &Aabb<D>| (0..D).map(|a| b.hi[a] - b.lo[a]).fold(0.0, f64::max);
    let mean_f = fboxes.iter().map(extent).sum::<f64>() / fboxes.len() as f64;
    let mean_p = pboxes.iter().map(extent).sum::<f64>() / pboxes.len() as f64;
    let mut cell = mean_f.max(mean_p);
    if !(cell > 0.0 && cell.is_finite()) {
        cell = 1.0;
    }
    // Every facet lies in `all`: a particle box outside it has no candidates (most particles
    // of a body far from, or only partly near, the other one) and needs no look-up.
    let all = fboxes.iter().skip(1).fold(fboxes[0], |u, b| Aabb {
        lo: u.lo.inf(&b.lo),
        hi: u.hi.sup(&b.hi),
    });
    let bins = Bins::build(fboxes, &all, cell);
    // Chunks of particles in parallel, each with one growing buffer (no allocation per
    // particle); concatenated in order.
    let chunks: Vec<(Vec<u32>, Vec<u32>)> = pboxes
        .par_chunks(1024)
        .map(|chunk| {
            let mut counts = Vec::with_capacity(chunk.len());
            let mut facets: Vec<u32> = Vec::new();
            for pb in chunk {
                if !all.overlaps(pb) {
                    counts.push(0);
                    continue;
                }
                let before = facets.len();
                let (lo, hi) = bins.range(pb);
                if ncells(&lo, &hi) > MAX_CELLS_PER_QUERY {
                    facets.extend(
                        (0..fboxes.len() as u32).filter(|&f| fboxes[f as usize].overlaps(pb)),
                    );
                } else {
                    // Only the cells that hold facets; a facet is reported from the lowest cell
                    // its range shares with the particle's, so once.
                    let lo: [i64; D] = std::array::from_fn(|a| lo[a].max(bins.glo[a]));
                    let hi: [i64; D] = std::array::from_fn(|a| hi[a].min(bins.ghi[a]));
                    if (0..D).all(|a| lo[a] <= hi[a]) {
                        for_each_cell(&lo, &hi, |c| {
                            let Some(k) = bins.cell_number(&c) else {
                                return;
                            };
                            let cell_facets =
                                &bins.facets[bins.start[k] as usize..bins.start[k + 1] as usize];
                            for &f in cell_facets {
                                let flo = &bins.flo[f as usize];
                                if (0..D).all(|a| c[a] == flo[a].max(lo[a]))
                                    && fboxes[f as usize].overlaps(pb)
                                {
                                    facets.push(f);
                                }
                            }
                        });
                    }
                    facets.extend(
                        bins.big
                            .iter()
                            .copied()
                            .filter(|&f| fboxes[f as usize].overlaps(pb)),
                    );
                }
                facets[before..].sort_unstable();
                counts.push((facets.len() - before) as u32);
            }
            (counts, facets)
        })
        .collect();
    for (counts, facets) in chunks {
        let mut k = *out.start.last().unwrap_or(&0);
        for c in counts {
            k += c;
            out.start.push(k);
        }
        out.facets.extend_from_slice(&facets);
    }
}

fn for_each_cell<const D: usize>(lo: &[i64; D], hi: &[i64; D], mut f: impl FnMut([i64; D])) {
    let mut c = *lo;
    loop {
        f(c);
        let mut a = 0;
        loop {
            if a == D {
                return;
            }
            if c[a] < hi[a] {
                c[a] += 1;
                break;
            }
            c[a] = lo[a];
            a += 1;
        }
    }
}
