//! Broad phase: which boundary facets each particle must be tested against.
//!
//! A uniform spatial hash over facet bounding boxes (inflated by the query distance), built once
//! per query: facets are binned into the cells their box overlaps, the `(cell, facet)` pairs
//! sorted, and each particle looks up the cells its own box overlaps. Cost grows linearly with
//! the number of particles and facets (not their product); memory with the occupied cells.
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
        .map(|f| {
            let pts: Vec<&SVector<f64, D>> =
                f[..D].iter().map(|&v| &boundary[v as usize]).collect();
            Aabb::of(&pts)
        })
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
        .map(|f| {
            let mut pts: Vec<&SVector<f64, D>> =
                f[..D].iter().map(|&v| &boundary0[v as usize]).collect();
            pts.extend(f[..D].iter().map(|&v| &boundary1[v as usize]));
            Aabb::of(&pts)
        })
        .collect();
    query(&pboxes, &fboxes, out);
}

/// Cell budget per query box before falling back to a scan of all facets.
const MAX_CELLS_PER_QUERY: usize = 4096;

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
    let inv = 1.0 / cell;
    let range = |b: &Aabb<D>| -> ([i64; D], [i64; D]) {
        (
            std::array::from_fn(|a| (b.lo[a] * inv).floor() as i64),
            std::array::from_fn(|a| (b.hi[a] * inv).floor() as i64),
        )
    };
    let ncells = |lo: &[i64; D], hi: &[i64; D]| -> usize {
        (0..D)
            .map(|a| (hi[a] - lo[a] + 1).max(0) as usize)
            .fold(1usize, |x, y| x.saturating_mul(y))
    };
    // Bin facets; huge facets go to a list every query scans.
    let mut pairs: Vec<([i64; D], u32)> = Vec::new();
    let mut big: Vec<u32> = Vec::new();
    for (f, b) in fboxes.iter().enumerate() {
        let (lo, hi) = range(b);
        if ncells(&lo, &hi) > MAX_CELLS_PER_QUERY {
            big.push(f as u32);
            continue;
        }
        for_each_cell(&lo, &hi, |c| pairs.push((c, f as u32)));
    }
    pairs.sort_unstable();
    let mut table: FxHashMap<[i64; D], (u32, u32)> = FxHashMap::default();
    let mut i = 0;
    while i < pairs.len() {
        let mut j = i + 1;
        while j < pairs.len() && pairs[j].0 == pairs[i].0 {
            j += 1;
        }
        table.insert(pairs[i].0, (i as u32, j as u32));
        i = j;
    }
    // Every facet lies in `all`: a particle box outside it has no candidates (most particles
    // of a body far from, or only partly near, the other one) and needs no look-up.
    let all = fboxes.iter().skip(1).fold(fboxes[0], |u, b| Aabb {
        lo: u.lo.inf(&b.lo),
        hi: u.hi.sup(&b.hi),
    });
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
                let (lo, hi) = range(pb);
                if ncells(&lo, &hi) > MAX_CELLS_PER_QUERY {
                    facets.extend(
                        (0..fboxes.len() as u32).filter(|&f| fboxes[f as usize].overlaps(pb)),
                    );
                } else {
                    for_each_cell(&lo, &hi, |c| {
                        if let Some(&(a, b)) = table.get(&c) {
                            for &(_, f) in &pairs[a as usize..b as usize] {
                                if fboxes[f as usize].overlaps(pb) {
                                    facets.push(f);
                                }
                            }
                        }
                    });
                    facets.extend(
                        big.iter()
                            .copied()
                            .filter(|&f| fboxes[f as usize].overlaps(pb)),
                    );
                }
                let mine = &mut facets[before..];
                mine.sort_unstable();
                let mut w = before;
                for r in before..facets.len() {
                    if r == before || facets[r] != facets[w - 1] {
                        facets[w] = facets[r];
                        w += 1;
                    }
                }
                facets.truncate(w);
                counts.push((w - before) as u32);
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
            c[a] += 1;
            if c[a] <= hi[a] {
                break;
            }
            c[a] = lo[a];
            a += 1;
        }
    }
}
