//! Gmsh `.msh` files: read ASCII 2.2 (parsed here) and 4.1 (ASCII or binary, parsed by the
//! `mshio` crate); write ASCII 2.2 and 4.1.
//!
//! Reading keeps the linear simplices of the mesh's dimension (3-node triangles in 2D, 4-node
//! tetrahedra in 3D), ignores lower-dimensional elements (points, lines, and in 3D surface
//! triangles — Gmsh writes them for physical groups), and rejects anything else (quads, hexes,
//! higher-order elements) with the line of the first such element. Nodes no cell uses are
//! dropped and the rest renumbered in order of their tags. A 2D mesh must lie in a plane
//! `z = const`. Every error names the file and, for ASCII files, the line.
//!
//! Refused, never repaired silently: a node tag defined twice, a tag of 0 (Gmsh numbers from 1),
//! section counts that do not match the entries (MSH 4.1: the header's node and element
//! counts and tag ranges against the blocks), an element tag repeated, two cells on the same
//! nodes (a cell counted twice would count its mass twice), and cells of inconsistent
//! orientation (a tangled mesh, or one whose tool ordered the nodes at random). A mesh whose
//! cells are *all* inverted is refused too, unless [`ReadOptions::reorient`] asks to flip them
//! (`"reorient": true` in a scene).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::SVector;

use super::Mesh;
use crate::FemError;

/// A node as read: tag, coordinates, 1-based line (0 if unknown).
struct RawNode {
    tag: u64,
    x: [f64; 3],
    line: usize,
}

/// How a mesh file is read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Flip every cell of a mesh whose cells are *all* negatively oriented (a consistently
    /// inverted mesh, as some tools write). Off: such a mesh is an error. A mesh with cells of
    /// both orientations is an error either way.
    pub reorient: bool,
}

/// An element as read: tag, Gmsh type, node tags, 1-based line (0 if unknown).
struct RawElement {
    tag: u64,
    kind: i64,
    nodes: Vec<u64>,
    line: usize,
}

fn file_error(path: &Path, line: usize, message: impl Into<String>) -> FemError {
    FemError::MeshFile {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// The largest mesh file [`read_msh`] reads (1 GiB); [`read_msh_limited`] takes another limit.
pub const MAX_MSH_BYTES: u64 = 1 << 30;

/// Read a Gmsh mesh file into a `D`-dimensional mesh (at most [`MAX_MSH_BYTES`]).
pub fn read_msh<const D: usize>(path: &Path) -> Result<Mesh<D>, FemError> {
    read_msh_limited(path, MAX_MSH_BYTES)
}

/// [`read_msh`] with options.
pub fn read_msh_with<const D: usize>(path: &Path, opts: ReadOptions) -> Result<Mesh<D>, FemError> {
    let bytes = read_regular_file(path, MAX_MSH_BYTES)?;
    parse_msh_with(&bytes, path, opts)
}

/// Read a Gmsh mesh file of at most `max_bytes` into a `D`-dimensional mesh. Only regular files
/// are read (a FIFO or a device such as `/dev/zero` is refused before it is opened for reading,
/// so it can neither block nor fill memory), and the read stops after `max_bytes`.
pub fn read_msh_limited<const D: usize>(path: &Path, max_bytes: u64) -> Result<Mesh<D>, FemError> {
    let bytes = read_regular_file(path, max_bytes)?;
    parse_msh(&bytes, path)
}

/// The bytes of the regular file `path`, refusing anything else and anything over `max_bytes`.
pub fn read_regular_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>, FemError> {
    use std::io::Read;
    let io = |source: std::io::Error| FemError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file (a directory, FIFO or device): meshes are read from regular files only",
        )));
    }
    if meta.len() > max_bytes {
        return Err(file_error(
            path,
            0,
            format!(
                "the file has {} bytes, more than the limit of {max_bytes}",
                meta.len()
            ),
        ));
    }
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // The file may grow between the size check and the read: read one byte past the limit.
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max_bytes {
        return Err(file_error(
            path,
            0,
            format!("the file grew past the limit of {max_bytes} bytes while it was read"),
        ));
    }
    Ok(bytes)
}

/// Parse the bytes of a Gmsh mesh file; `path` is only used in error messages.
pub fn parse_msh<const D: usize>(bytes: &[u8], path: &Path) -> Result<Mesh<D>, FemError> {
    parse_msh_with(bytes, path, ReadOptions::default())
}

/// [`parse_msh`] with options.
pub fn parse_msh_with<const D: usize>(
    bytes: &[u8],
    path: &Path,
    opts: ReadOptions,
) -> Result<Mesh<D>, FemError> {
    let (version, binary) = header(bytes, path)?;
    let (nodes, elements) = if (2.0..3.0).contains(&version) {
        if binary {
            return Err(file_error(
                path,
                2,
                "binary MSH 2.x is not supported: save as ASCII 2.2, or as MSH 4.1",
            ));
        }
        parse_v2(bytes, path)?
    } else if (version - 4.1).abs() < 1e-9 {
        if !binary {
            check_v41_sections(bytes, path)?;
        }
        parse_v41(bytes, path, binary)?
    } else {
        return Err(file_error(
            path,
            2,
            format!("MSH version {version} is not supported: save as MSH 4.1 or 2.2"),
        ));
    };
    assemble::<D>(nodes, elements, path, opts)
}

/// Version and binary flag from `$MeshFormat`.
fn header(bytes: &[u8], path: &Path) -> Result<(f64, bool), FemError> {
    let head = &bytes[..bytes.len().min(256)];
    let text = String::from_utf8_lossy(head);
    let mut lines = text.lines();
    if lines.next().map(str::trim) != Some("$MeshFormat") {
        return Err(file_error(
            path,
            1,
            "not a Gmsh file: expected `$MeshFormat` on the first line",
        ));
    }
    let fmt = lines
        .next()
        .ok_or_else(|| file_error(path, 2, "missing the `version file-type data-size` line"))?;
    let mut it = fmt.split_whitespace();
    let version: f64 = it
        .next()
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| file_error(path, 2, format!("cannot read the MSH version from `{fmt}`")))?;
    let file_type: i64 = it
        .next()
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| file_error(path, 2, format!("cannot read the file type from `{fmt}`")))?;
    Ok((version, file_type == 1))
}

/// ASCII MSH 2.x.
fn parse_v2(bytes: &[u8], path: &Path) -> Result<(Vec<RawNode>, Vec<RawElement>), FemError> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| file_error(path, 0, format!("not valid UTF-8 text: {e}")))?;
    let lines: Vec<&str> = text.lines().collect();
    let find = |name: &str| lines.iter().position(|l| l.trim() == name);
    // A count is at most the lines left in the file (each entry takes one): a corrupted count
    // must not size an allocation or overflow an index.
    let count_at = |i: usize, what: &str| -> Result<usize, FemError> {
        let n: usize = lines
            .get(i)
            .and_then(|l| l.trim().parse().ok())
            .ok_or_else(|| file_error(path, i + 1, format!("expected the number of {what}")))?;
        let left = lines.len().saturating_sub(i + 1);
        if n > left {
            return Err(file_error(
                path,
                i + 1,
                format!("{n} {what} declared, but the file has only {left} more lines"),
            ));
        }
        Ok(n)
    };
    let n0 = find("$Nodes").ok_or_else(|| file_error(path, 0, "no `$Nodes` section"))?;
    let nn = count_at(n0 + 1, "nodes")?;
    let mut nodes = Vec::with_capacity(nn);
    for i in n0 + 2..n0 + 2 + nn {
        let l = lines
            .get(i)
            .ok_or_else(|| file_error(path, i + 1, "file ends inside `$Nodes`"))?;
        let t: Vec<&str> = l.split_whitespace().collect();
        let parse = |k: usize| t.get(k).and_then(|v| v.parse::<f64>().ok());
        match (
            t.first().and_then(|v| v.parse::<u64>().ok()),
            parse(1),
            parse(2),
            parse(3),
        ) {
            (Some(tag), Some(x), Some(y), Some(z)) => nodes.push(RawNode {
                tag,
                x: [x, y, z],
                line: i + 1,
            }),
            _ => {
                return Err(file_error(
                    path,
                    i + 1,
                    format!("malformed node line `{l}` (expected `tag x y z`)"),
                ));
            }
        }
    }
    if lines.get(n0 + 2 + nn).map(|l| l.trim()) != Some("$EndNodes") {
        return Err(file_error(
            path,
            n0 + 3 + nn,
            "expected `$EndNodes` (node count does not match)",
        ));
    }
    let e0 = find("$Elements").ok_or_else(|| file_error(path, 0, "no `$Elements` section"))?;
    let ne = count_at(e0 + 1, "elements")?;
    let mut elements = Vec::with_capacity(ne);
    for i in e0 + 2..e0 + 2 + ne {
        let l = lines
            .get(i)
            .ok_or_else(|| file_error(path, i + 1, "file ends inside `$Elements`"))?;
        let t: Result<Vec<u64>, _> = l.split_whitespace().map(str::parse::<u64>).collect();
        let t = t.map_err(|_| file_error(path, i + 1, format!("malformed element line `{l}`")))?;
        if t.len() < 3 || (t.len() as u64 - 3) < t[2] {
            return Err(file_error(
                path,
                i + 1,
                format!("malformed element line `{l}`"),
            ));
        }
        let ntags = t[2] as usize;
        elements.push(RawElement {
            tag: t[0],
            kind: t[1] as i64,
            nodes: t[3 + ntags..].to_vec(),
            line: i + 1,
        });
    }
    if lines.get(e0 + 2 + ne).map(|l| l.trim()) != Some("$EndElements") {
        return Err(file_error(
            path,
            e0 + 3 + ne,
            "expected `$EndElements` (element count does not match)",
        ));
    }
    Ok((nodes, elements))
}

/// MSH 4.1 through `mshio`.
fn parse_v41(
    bytes: &[u8],
    path: &Path,
    binary: bool,
) -> Result<(Vec<RawNode>, Vec<RawElement>), FemError> {
    let line_of = |offset: usize| -> usize {
        if binary {
            0
        } else {
            bytes[..offset.min(bytes.len())]
                .iter()
                .filter(|&&b| b == b'\n')
                .count()
                + 1
        }
    };
    // mshio documents a few remaining `expect`s on malformed input; keep them from unwinding
    // into the caller.
    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(bytes).map_err(|e| {
            let (at, kind) = e
                .begin_msh_errors()
                .next()
                .map(|(at, k)| (*at, k.to_string()))
                .unwrap_or((bytes, "malformed file".to_string()));
            let offset = (at.as_ptr() as usize).saturating_sub(bytes.as_ptr() as usize);
            (offset, kind)
        })
    });
    let msh = match parsed {
        Ok(Ok(m)) => m,
        Ok(Err((offset, kind))) => return Err(file_error(path, line_of(offset), kind)),
        Err(_) => {
            return Err(file_error(
                path,
                0,
                "malformed MSH 4.1 file (the parser gave up)",
            ));
        }
    };
    let mut nodes = Vec::new();
    if let Some(n) = &msh.data.nodes {
        for block in &n.node_blocks {
            // Node tags: explicit map when sparse, else consecutive from the block's first tag.
            let tags: Vec<u64> = match &block.node_tags {
                Some(map) => {
                    let mut t = vec![0u64; block.nodes.len()];
                    for (&tag, &i) in map {
                        t[i] = tag;
                    }
                    t
                }
                None => Vec::new(),
            };
            for (i, nd) in block.nodes.iter().enumerate() {
                let tag = if tags.is_empty() { 0 } else { tags[i] };
                nodes.push(RawNode {
                    tag,
                    x: [nd.x, nd.y, nd.z],
                    line: 0,
                });
            }
        }
        // Dense blocks carry no tags: they are numbered consecutively from min_node_tag.
        if nodes.iter().all(|n| n.tag == 0) {
            for (i, nd) in nodes.iter_mut().enumerate() {
                nd.tag = n.min_node_tag + i as u64;
            }
        }
    }
    let mut elements = Vec::new();
    if let Some(e) = &msh.data.elements {
        for block in &e.element_blocks {
            for el in &block.elements {
                elements.push(RawElement {
                    tag: el.element_tag,
                    kind: block.element_type as i64,
                    nodes: el.nodes.clone(),
                    line: 0,
                });
            }
        }
    }
    if !binary {
        locate_v41_elements(bytes, &mut elements);
    }
    Ok((nodes, elements))
}

/// Fill in the line of each element of an ASCII 4.1 file (for error messages).
fn locate_v41_elements(bytes: &[u8], elements: &mut [RawElement]) {
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    let mut lines = text.lines().enumerate();
    if lines
        .by_ref()
        .find(|(_, l)| l.trim() == "$Elements")
        .is_none()
    {
        return;
    }
    let Some((_, head)) = lines.next() else {
        return;
    };
    let nblocks: usize = head
        .split_whitespace()
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let mut by_tag: HashMap<u64, usize> = HashMap::new();
    for _ in 0..nblocks {
        let Some((_, bh)) = lines.next() else { break };
        let count: usize = bh
            .split_whitespace()
            .nth(3)
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        for _ in 0..count {
            let Some((i, l)) = lines.next() else { break };
            if let Some(tag) = l.split_whitespace().next().and_then(|v| v.parse().ok()) {
                by_tag.insert(tag, i + 1);
            }
        }
    }
    for e in elements.iter_mut() {
        e.line = by_tag.get(&e.tag).copied().unwrap_or(0);
    }
}

fn type_name(kind: i64) -> &'static str {
    match kind {
        1 => "2-node line",
        2 => "3-node triangle",
        3 => "4-node quadrangle",
        4 => "4-node tetrahedron",
        5 => "8-node hexahedron",
        6 => "6-node prism",
        7 => "5-node pyramid",
        8 => "3-node line",
        9 => "6-node triangle",
        11 => "10-node tetrahedron",
        15 => "point",
        _ => "higher-order or unknown element",
    }
}

/// ` (line N)` for a line number, nothing for 0 (unknown).
fn on_line(line: usize) -> String {
    if line > 0 {
        format!(" (line {line})")
    } else {
        String::new()
    }
}

/// The same cell twice (same nodes in any order) is an error: its mass and stiffness would
/// count twice.
fn no_cell_twice<const D: usize>(
    cells: &[[usize; 4]],
    cells_raw: &[&RawElement],
    path: &Path,
) -> Result<(), FemError> {
    let mut by_nodes: HashMap<Vec<usize>, usize> = HashMap::with_capacity(cells.len());
    for (k, c) in cells.iter().enumerate() {
        let mut key = c[..=D].to_vec();
        key.sort_unstable();
        if let Some(first) = by_nodes.insert(key, k) {
            return Err(file_error(
                path,
                cells_raw[k].line,
                format!(
                    "element {} has the same nodes as element {}{}: a cell written twice would \
                     count its mass and stiffness twice",
                    cells_raw[k].tag,
                    cells_raw[first].tag,
                    on_line(cells_raw[first].line)
                ),
            ));
        }
    }
    Ok(())
}

/// Node and element tags: from 1, each defined once.
fn unique_tags(nodes: &[RawNode], elements: &[RawElement], path: &Path) -> Result<(), FemError> {
    let mut seen: HashMap<u64, usize> = HashMap::with_capacity(nodes.len());
    for n in nodes {
        if n.tag == 0 {
            return Err(file_error(
                path,
                n.line,
                "node tag 0: Gmsh numbers nodes from 1",
            ));
        }
        if let Some(first) = seen.insert(n.tag, n.line) {
            return Err(file_error(
                path,
                n.line,
                format!(
                    "node {} is defined twice{}: a node tag names one node",
                    n.tag,
                    on_line(first).replace("line", "first on line")
                ),
            ));
        }
    }
    let mut seen: HashMap<u64, usize> = HashMap::with_capacity(elements.len());
    for e in elements {
        if e.tag == 0 {
            return Err(file_error(
                path,
                e.line,
                "element tag 0: Gmsh numbers elements from 1",
            ));
        }
        if let Some(first) = seen.insert(e.tag, e.line) {
            return Err(file_error(
                path,
                e.line,
                format!(
                    "element {} is defined twice{}",
                    e.tag,
                    on_line(first).replace("line", "first on line")
                ),
            ));
        }
    }
    Ok(())
}

/// The linear simplices of the file (triangles in 2D, tetrahedra in 3D); lower-dimensional
/// elements and points are skipped, any other element type is an error.
fn linear_cells<'e, const D: usize>(
    elements: &'e [RawElement],
    path: &Path,
) -> Result<Vec<&'e RawElement>, FemError> {
    let (want, ignore): (i64, &[i64]) = if D == 2 {
        (2, &[1, 8, 15])
    } else {
        (4, &[1, 2, 8, 9, 15])
    };
    let mut cells_raw = Vec::new();
    for e in elements {
        if e.kind == want {
            if e.nodes.len() != D + 1 {
                return Err(file_error(
                    path,
                    e.line,
                    format!(
                        "element {} has {} nodes, expected {}",
                        e.tag,
                        e.nodes.len(),
                        D + 1
                    ),
                ));
            }
            cells_raw.push(e);
        } else if !ignore.contains(&e.kind) {
            return Err(file_error(
                path,
                e.line,
                format!(
                    "element {} is a {} (Gmsh type {}); femp reads linear triangles in 2D and \
                     linear tetrahedra in 3D",
                    e.tag,
                    type_name(e.kind),
                    e.kind
                ),
            ));
        }
    }
    if cells_raw.is_empty() {
        return Err(file_error(
            path,
            0,
            format!(
                "no {} in the file",
                if D == 2 {
                    "3-node triangles"
                } else {
                    "4-node tetrahedra"
                }
            ),
        ));
    }
    Ok(cells_raw)
}

fn assemble<const D: usize>(
    nodes: Vec<RawNode>,
    elements: Vec<RawElement>,
    path: &Path,
    opts: ReadOptions,
) -> Result<Mesh<D>, FemError> {
    unique_tags(&nodes, &elements, path)?;
    let cells_raw = linear_cells::<D>(&elements, path)?;
    let index: HashMap<u64, usize> = nodes.iter().enumerate().map(|(i, n)| (n.tag, i)).collect();
    let mut used = vec![false; nodes.len()];
    for e in &cells_raw {
        for t in &e.nodes {
            match index.get(t) {
                Some(&i) => used[i] = true,
                None => {
                    return Err(file_error(
                        path,
                        e.line,
                        format!(
                            "element {} references node {t}, which the file does not define",
                            e.tag
                        ),
                    ));
                }
            }
        }
    }
    // Compact numbering in order of node tags.
    let mut order: Vec<usize> = (0..nodes.len()).filter(|&i| used[i]).collect();
    order.sort_by_key(|&i| nodes[i].tag);
    let mut new_id = vec![usize::MAX; nodes.len()];
    for (k, &i) in order.iter().enumerate() {
        new_id[i] = k;
    }
    if D == 2 {
        let z0 = nodes[order[0]].x[2];
        let scale = order
            .iter()
            .map(|&i| nodes[i].x[0].abs().max(nodes[i].x[1].abs()))
            .fold(1e-300, f64::max);
        if let Some(&bad) = order
            .iter()
            .find(|&&i| (nodes[i].x[2] - z0).abs() > 1e-9 * scale)
        {
            return Err(file_error(
                path,
                0,
                format!(
                    "a 2D mesh must lie in a plane z = const; node {} has z = {} (first node: {z0})",
                    nodes[bad].tag, nodes[bad].x[2]
                ),
            ));
        }
    }
    let vertices: Vec<SVector<f64, D>> = order
        .iter()
        .map(|&i| SVector::from_fn(|a, _| nodes[i].x[a]))
        .collect();
    let cells: Vec<[usize; 4]> = cells_raw
        .iter()
        .map(|e| {
            let mut c = [usize::MAX; 4];
            for (k, t) in e.nodes.iter().enumerate() {
                c[k] = new_id[index[t]];
            }
            c
        })
        .collect();
    no_cell_twice::<D>(&cells, &cells_raw, path)?;
    let mesh = Mesh::new_oriented(vertices.clone(), cells.clone()).map_err(|err| match err {
        FemError::DegenerateCell {
            cell,
            volume,
            reason,
        } => file_error(
            path,
            cells_raw[cell].line,
            format!(
                "element {} is degenerate: it {reason} (volume {volume:e})",
                cells_raw[cell].tag
            ),
        ),
        other => other,
    })?;
    // Orientation: consistent, and positive unless the caller asked to flip an inverted mesh.
    let probe = Mesh::<D> {
        vertices,
        cells: Vec::new(),
    };
    let negative: Vec<usize> = (0..cells.len())
        .filter(|&k| probe.signed_volume_of(&cells[k]) < 0.0)
        .collect();
    if negative.len() == cells.len() {
        if !opts.reorient {
            return Err(file_error(
                path,
                cells_raw[0].line,
                format!(
                    "every element is inverted (negative {}; element {} the first): the file's \
                     node order is reversed — set `\"reorient\": true` on the mesh to flip every \
                     element, or re-export it",
                    if D == 2 { "area" } else { "volume" },
                    cells_raw[0].tag
                ),
            ));
        }
    } else if let Some(&k) = negative.first() {
        // Name an element of the minority orientation.
        let k = if 2 * negative.len() > cells.len() {
            let mut neg = vec![false; cells.len()];
            negative.iter().for_each(|&i| neg[i] = true);
            (0..cells.len()).find(|&i| !neg[i]).unwrap_or(k)
        } else {
            k
        };
        return Err(file_error(
            path,
            cells_raw[k].line,
            format!(
                "element {} is oriented opposite to {} of the mesh's {} elements: a tangled mesh \
                 (an element folded over its neighbours) or one whose nodes were ordered at \
                 random — femp does not guess which; re-export it with consistent orientation",
                cells_raw[k].tag,
                if 2 * negative.len() > cells.len() {
                    negative.len()
                } else {
                    cells.len() - negative.len()
                },
                cells.len()
            ),
        ));
    }
    Ok(mesh)
}

/// MSH 4.1 ASCII: the section headers' counts and tag ranges against what the blocks hold
/// (`mshio` trusts the header: a dense tag range makes it drop the tags the file lists).
fn check_v41_sections(bytes: &[u8], path: &Path) -> Result<(), FemError> {
    let Ok(text) = std::str::from_utf8(bytes) else {
        return Ok(()); // mshio reports it
    };
    let lines: Vec<&str> = text.lines().collect();
    let nums = |i: usize| -> Option<Vec<u64>> {
        lines
            .get(i)?
            .split_whitespace()
            .map(|t| t.parse().ok())
            .collect()
    };
    for (section, what) in [("$Nodes", "nodes"), ("$Elements", "elements")] {
        let Some(s0) = lines.iter().position(|l| l.trim() == section) else {
            continue;
        };
        let bad = |i: usize, m: String| Err(file_error(path, i + 1, m));
        let Some(head) = nums(s0 + 1).filter(|h| h.len() >= 4) else {
            return bad(s0 + 1, format!("malformed `{section}` header"));
        };
        let (blocks, total, min_tag, max_tag) = (head[0], head[1], head[2], head[3]);
        let mut i = s0 + 2;
        let mut count = 0u64;
        let mut tags: HashMap<u64, usize> = HashMap::new();
        for _ in 0..blocks {
            let Some(bh) = nums(i).filter(|b| b.len() >= 4) else {
                return bad(i, format!("malformed {what} block header"));
            };
            let n = bh[3];
            if n > lines.len() as u64 {
                return bad(
                    i,
                    format!("a block of {n} {what} in a file of {} lines", lines.len()),
                );
            }
            i += 1;
            let mut tag_lines = Vec::with_capacity(n as usize);
            for _ in 0..n {
                let Some(t) = lines
                    .get(i)
                    .and_then(|l| l.split_whitespace().next()?.parse::<u64>().ok())
                else {
                    return bad(i, format!("expected a {} tag", &what[..what.len() - 1]));
                };
                tag_lines.push((t, i + 1));
                i += 1;
            }
            if what == "nodes" {
                i += n as usize; // the coordinates follow the tags
            }
            for (t, line) in tag_lines {
                if t == 0 || t < min_tag || t > max_tag {
                    return bad(
                        line - 1,
                        format!(
                            "{} tag {t} is outside the range {min_tag}–{max_tag} the `{section}` \
                             header declares (Gmsh tags start at 1)",
                            &what[..what.len() - 1]
                        ),
                    );
                }
                if let Some(first) = tags.insert(t, line) {
                    return bad(
                        line - 1,
                        format!(
                            "{} {t} is defined twice (first on line {first})",
                            &what[..what.len() - 1]
                        ),
                    );
                }
            }
            count += n;
        }
        if count != total {
            return bad(
                s0 + 1,
                format!("the `{section}` header declares {total} {what}, its blocks hold {count}"),
            );
        }
    }
    Ok(())
}

fn write_file(path: &Path, text: &str) -> Result<(), FemError> {
    std::fs::write(path, text).map_err(|source| FemError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The mesh as ASCII MSH 2.2 text (tags are 1-based indices).
pub fn to_msh22<const D: usize>(mesh: &Mesh<D>) -> String {
    let mut s = String::new();
    s.push_str("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    let _ = writeln!(s, "{}", mesh.num_vertices());
    for (i, x) in mesh.vertices().iter().enumerate() {
        let z = if D == 3 { x[D - 1] } else { 0.0 };
        let _ = writeln!(s, "{} {:e} {:e} {:e}", i + 1, x[0], x[1], z);
    }
    s.push_str("$EndNodes\n$Elements\n");
    let _ = writeln!(s, "{}", mesh.num_cells());
    let kind = if D == 2 { 2 } else { 4 };
    for e in 0..mesh.num_cells() {
        let _ = write!(s, "{} {kind} 2 1 1", e + 1);
        for v in mesh.cell(e) {
            let _ = write!(s, " {}", v + 1);
        }
        s.push('\n');
    }
    s.push_str("$EndElements\n");
    s
}

/// The mesh as ASCII MSH 4.1 text (one entity, tags are 1-based indices).
pub fn to_msh41<const D: usize>(mesh: &Mesh<D>) -> String {
    let (n, m) = (mesh.num_vertices(), mesh.num_cells());
    let mut s = String::new();
    s.push_str("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
    // One entity of dimension D with tag 1 (no bounding entities).
    let (lo, hi) = mesh.bounding_box();
    let bb =
        |v: &SVector<f64, D>| -> [f64; 3] { [v[0], v[1], if D == 3 { v[D - 1] } else { 0.0 }] };
    let (l, h) = (bb(&lo), bb(&hi));
    s.push_str("$Entities\n");
    let _ = writeln!(
        s,
        "0 0 {} {}",
        if D == 2 { 1 } else { 0 },
        if D == 3 { 1 } else { 0 }
    );
    let _ = writeln!(
        s,
        "1 {:e} {:e} {:e} {:e} {:e} {:e} 0 0",
        l[0], l[1], l[2], h[0], h[1], h[2]
    );
    s.push_str("$EndEntities\n$Nodes\n");
    let _ = writeln!(s, "1 {n} 1 {n}");
    let _ = writeln!(s, "{D} 1 0 {n}");
    for i in 0..n {
        let _ = writeln!(s, "{}", i + 1);
    }
    for x in mesh.vertices() {
        let c = bb(x);
        let _ = writeln!(s, "{:e} {:e} {:e}", c[0], c[1], c[2]);
    }
    s.push_str("$EndNodes\n$Elements\n");
    let _ = writeln!(s, "1 {m} 1 {m}");
    let _ = writeln!(s, "{D} 1 {} {m}", if D == 2 { 2 } else { 4 });
    for e in 0..m {
        let _ = write!(s, "{}", e + 1);
        for v in mesh.cell(e) {
            let _ = write!(s, " {}", v + 1);
        }
        s.push('\n');
    }
    s.push_str("$EndElements\n");
    s
}

/// Write ASCII MSH 2.2.
pub fn write_msh22<const D: usize>(path: &Path, mesh: &Mesh<D>) -> Result<(), FemError> {
    write_file(path, &to_msh22(mesh))
}

/// Write ASCII MSH 4.1.
pub fn write_msh41<const D: usize>(path: &Path, mesh: &Mesh<D>) -> Result<(), FemError> {
    write_file(path, &to_msh41(mesh))
}
