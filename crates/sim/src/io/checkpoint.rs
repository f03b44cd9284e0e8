//! `checkpoint.femp`: a run's state between steps, on disk ([`Checkpoint`]), so a run stopped
//! for any reason — an interrupt, a machine going down, a session's end — continues from its
//! last frame instead of from the start (`femp run --checkpoint`, `--resume`; docs/scenes.md).
//!
//! The file: the 8 bytes `FEMPCKPT`, the format's version (u32), the length of a JSON header
//! (u64) and the header — the world's [`StateHeader`], the run's recorder state and the counts
//! that follow —, the bodies' numbers (f64), the solvers' analysed patterns (u32: DOF map,
//! column pointers, row indices), and an FNV-1a hash of everything before it (u64); all
//! little-endian. It is written to a temporary name and renamed, so a checkpoint is whole or
//! absent; a truncated or altered one is refused with what is wrong.

use std::path::Path;

use femp_solver::AnalysedPattern;
use serde::{Deserialize, Serialize};

use crate::error::SimError;
use crate::state::{Fnv, StateHeader, WorldState};

/// The checkpoint's file name in a run's output directory.
pub const CHECKPOINT: &str = "checkpoint.femp";

const MAGIC: &[u8; 8] = b"FEMPCKPT";
const VERSION: u32 = 1;

/// A world's state with what the run recording it had written by then.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    /// The world.
    pub world: WorldState,
    /// The recorder's state (`run::Recorder`), as JSON.
    pub(crate) run: serde_json::Value,
}

#[derive(Serialize, Deserialize)]
struct Header {
    world: StateHeader,
    run: serde_json::Value,
    floats: usize,
    /// Per solver: lengths of the DOF map, column pointers and row indices, if analysed.
    patterns: [Option<[usize; 3]>; 2],
}

fn bad(path: &Path, message: impl Into<String>) -> SimError {
    SimError::Checkpoint {
        what: path.display().to_string(),
        message: message.into(),
    }
}

impl Checkpoint {
    /// A checkpoint of `world` alone, without a run's outputs (for code that steps a world
    /// itself: [`World::restore`] puts a world built from the same scene back where this one is).
    pub fn for_world<const D: usize>(world: &crate::World<D>) -> Result<Self, SimError> {
        Ok(Self {
            world: world.state()?,
            run: serde_json::Value::Null,
        })
    }

    /// Write to `path` (through `path.tmp`, renamed over it).
    pub fn write(&self, path: &Path) -> Result<(), SimError> {
        let w = &self.world;
        let header = Header {
            world: w.header.clone(),
            run: self.run.clone(),
            floats: w.floats.len(),
            patterns: [0, 1].map(|k| {
                w.patterns[k]
                    .as_ref()
                    .map(|p| [p.dof_of.len(), p.col_ptr.len(), p.row_idx.len()])
            }),
        };
        let text = serde_json::to_vec(&header).map_err(|e| bad(path, e.to_string()))?;
        let ints: usize = w
            .patterns
            .iter()
            .flatten()
            .map(|p| p.dof_of.len() + p.col_ptr.len() + p.row_idx.len())
            .sum();
        let mut bytes = Vec::with_capacity(28 + text.len() + 8 * w.floats.len() + 4 * ints);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&VERSION.to_le_bytes());
        bytes.extend_from_slice(&(text.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&text);
        for x in &w.floats {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
        for p in w.patterns.iter().flatten() {
            for v in [&p.dof_of, &p.col_ptr, &p.row_idx] {
                for &i in v.iter() {
                    let i = u32::try_from(i)
                        .map_err(|_| bad(path, "a solver's pattern has more than 2³² entries"))?;
                    bytes.extend_from_slice(&i.to_le_bytes());
                }
            }
        }
        let mut h = Fnv::new();
        h.bytes(&bytes);
        bytes.extend_from_slice(&h.0.to_le_bytes());
        let tmp = path.with_extension("femp.tmp");
        let io = |p: &Path| {
            let p = p.to_path_buf();
            move |source| SimError::Io { path: p, source }
        };
        std::fs::write(&tmp, &bytes).map_err(io(&tmp))?;
        std::fs::rename(&tmp, path).map_err(io(path))
    }

    /// Read `path`; a file that is not a checkpoint of this format, or truncated, or altered, is
    /// an error saying which.
    pub fn read(path: &Path) -> Result<Self, SimError> {
        let bytes = std::fs::read(path).map_err(|source| SimError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        if bytes.len() < 28 || &bytes[..8] != MAGIC {
            return Err(bad(path, "not a femp checkpoint"));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        let mut h = Fnv::new();
        h.bytes(body);
        let stored = u64::from_le_bytes(tail.try_into().expect("8 bytes"));
        let version = u32::from_le_bytes(body[8..12].try_into().expect("4 bytes"));
        if version != VERSION {
            return Err(bad(
                path,
                format!("checkpoint format {version}; this femp reads format {VERSION}"),
            ));
        }
        if stored != h.0 {
            return Err(bad(
                path,
                "its contents do not match their checksum (truncated or altered)",
            ));
        }
        let len = u64::from_le_bytes(body[12..20].try_into().expect("8 bytes")) as usize;
        let rest = &body[20..];
        if len > rest.len() {
            return Err(bad(path, "its header runs past the end of the file"));
        }
        let header: Header =
            serde_json::from_slice(&rest[..len]).map_err(|e| bad(path, format!("header: {e}")))?;
        let mut data = &rest[len..];
        let ints: usize = header.patterns.iter().flatten().flatten().sum();
        if data.len() != 8 * header.floats + 4 * ints {
            return Err(bad(
                path,
                format!(
                    "{} bytes of data where its header announces {}",
                    data.len(),
                    8 * header.floats + 4 * ints
                ),
            ));
        }
        let floats = data[..8 * header.floats]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect();
        data = &data[8 * header.floats..];
        let mut take = |n: usize| -> Vec<usize> {
            let (head, tail) = data.split_at(4 * n);
            data = tail;
            head.chunks_exact(4)
                .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")) as usize)
                .collect()
        };
        let patterns = header.patterns.map(|p| {
            p.map(|[a, b, c]| AnalysedPattern {
                dof_of: take(a),
                col_ptr: take(b),
                row_idx: take(c),
            })
        });
        Ok(Self {
            world: WorldState {
                header: header.world,
                floats,
                patterns,
            },
            run: header.run,
        })
    }

    /// The step the checkpoint was taken after.
    pub fn step(&self) -> usize {
        self.world.header.step
    }

    /// The simulated time it was taken at (s).
    pub fn time(&self) -> f64 {
        self.world.header.time
    }
}
