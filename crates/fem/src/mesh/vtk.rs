//! VTK XML unstructured grids (`.vtu`) and ParaView collections (`.pvd`).
//!
//! A small writer rather than `vtkio` (whose dependencies are old): [`Vtu`] holds points (always
//! 3 components; 2D data gets z = 0), cells (simplices or one vertex per point, for particles)
//! and named point and cell fields. [`Vtu::write`] writes either readable ASCII or compact raw
//! binary (appended, little-endian, `UInt64` headers); both open in ParaView. [`Vtu::read`]
//! reads back files written here (used by tests and by the renderer), not arbitrary VTK files.
//! [`Pvd`] keeps a time series and rewrites its `.pvd` after every frame, so an interrupted run
//! leaves a valid collection of the frames written so far.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{SMatrix, SVector};

use super::Mesh;
use crate::FemError;

/// VTK cell type codes used here.
const VTK_VERTEX: u8 = 1;
const VTK_TRIANGLE: u8 = 5;
const VTK_TETRA: u8 = 10;

/// How array data is stored in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Encoding {
    /// Human-readable numbers.
    Ascii,
    /// Raw little-endian binary in an appended section (smaller and faster).
    #[default]
    Binary,
}

/// A named field with `components` values per point or per cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    /// Name shown in ParaView.
    pub name: String,
    /// Values per entry (1 scalar, 3 vector).
    pub components: usize,
    /// `components × count` values, entry-major.
    pub values: Vec<f64>,
}

impl Field {
    /// A scalar field.
    pub fn scalar(name: &str, values: Vec<f64>) -> Self {
        Self {
            name: name.to_string(),
            components: 1,
            values,
        }
    }

    /// A vector field from `D`-vectors (padded to 3 components).
    pub fn vector<const D: usize>(name: &str, v: &[SVector<f64, D>]) -> Self {
        let mut values = Vec::with_capacity(3 * v.len());
        for x in v {
            for a in 0..3 {
                values.push(if a < D { x[a] } else { 0.0 });
            }
        }
        Self {
            name: name.to_string(),
            components: 3,
            values,
        }
    }
}

impl Field {
    /// A tensor field from `D × D` matrices, padded to 3 × 3 (9 components, row-major, as
    /// ParaView reads tensors).
    pub fn tensor<const D: usize>(name: &str, m: &[SMatrix<f64, D, D>]) -> Self {
        let mut values = Vec::with_capacity(9 * m.len());
        for t in m {
            for r in 0..3 {
                for c in 0..3 {
                    values.push(if r < D && c < D { t[(r, c)] } else { 0.0 });
                }
            }
        }
        Self {
            name: name.to_string(),
            components: 9,
            values,
        }
    }
}

/// One unstructured grid.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Vtu {
    /// Point coordinates.
    pub points: Vec<[f64; 3]>,
    /// Vertices per cell (1 for point clouds, 3 triangles, 4 tetrahedra).
    pub nodes_per_cell: usize,
    /// Cell connectivity, `nodes_per_cell` indices per cell.
    pub connectivity: Vec<usize>,
    /// Point fields.
    pub point_data: Vec<Field>,
    /// Cell fields.
    pub cell_data: Vec<Field>,
}

/// The value of attribute `key` in the XML start tag `tag`.
fn attr(tag: &str, key: &str) -> Option<String> {
    let k = format!("{key}=\"");
    let i = tag.find(&k)? + k.len();
    let j = tag[i..].find('"')? + i;
    Some(tag[i..j].to_string())
}

/// Every DataArray of a section as (name, components, f64 values): ASCII inline, or raw in
/// the appended `blob`; `bad` makes the error for a malformed one.
fn data_arrays(
    sec: &str,
    blob: &[u8],
    bad: &impl Fn(String) -> FemError,
) -> Result<Vec<(String, usize, Vec<f64>)>, FemError> {
    let mut out = Vec::new();
    let mut rest = sec;
    while let Some(i) = rest.find("<DataArray") {
        let end = rest[i..]
            .find('>')
            .ok_or_else(|| bad("unterminated DataArray".into()))?
            + i;
        let tag = &rest[i..=end];
        let name = attr(tag, "Name").unwrap_or_default();
        let comps: usize = attr(tag, "NumberOfComponents")
            .and_then(|v| v.parse().ok())
            .unwrap_or(1);
        let ty = attr(tag, "type").unwrap_or_default();
        let values: Vec<f64> = if attr(tag, "format").as_deref() == Some("appended") {
            let off: usize = attr(tag, "offset")
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| bad("appended array without offset".into()))?;
            let hdr = blob
                .get(off..off + 8)
                .ok_or_else(|| bad("appended offset out of range".into()))?;
            let len = u64::from_le_bytes(hdr.try_into().unwrap_or([0; 8])) as usize;
            let data = blob
                .get(off + 8..off + 8 + len)
                .ok_or_else(|| bad("appended array truncated".into()))?;
            match ty.as_str() {
                "Float64" | "Int64" => data
                    .chunks_exact(8)
                    .map(|c| {
                        let b: [u8; 8] = c.try_into().unwrap_or([0; 8]);
                        if ty == "Float64" {
                            f64::from_le_bytes(b)
                        } else {
                            i64::from_le_bytes(b) as f64
                        }
                    })
                    .collect(),
                "UInt8" => data.iter().map(|&b| b as f64).collect(),
                other => return Err(bad(format!("unsupported array type {other}"))),
            }
        } else {
            let close = rest[end..]
                .find("</DataArray>")
                .ok_or_else(|| bad("unterminated DataArray".into()))?
                + end;
            let body = &rest[end + 1..close];
            body.split_whitespace()
                .map(|t| {
                    t.parse::<f64>()
                        .map_err(|_| bad(format!("bad number `{t}` in {name}")))
                })
                .collect::<Result<_, _>>()?
        };
        out.push((name, comps, values));
        rest = &rest[end + 1..];
    }
    Ok(out)
}

impl Vtu {
    /// A grid of the mesh's cells at positions `x` (one per mesh vertex).
    pub fn from_mesh<const D: usize>(mesh: &Mesh<D>, x: &[SVector<f64, D>]) -> Self {
        let mut connectivity = Vec::with_capacity((D + 1) * mesh.num_cells());
        for e in 0..mesh.num_cells() {
            connectivity.extend_from_slice(mesh.cell(e));
        }
        Self {
            points: pad(x),
            nodes_per_cell: D + 1,
            connectivity,
            point_data: Vec::new(),
            cell_data: Vec::new(),
        }
    }

    /// A point cloud (one VTK vertex cell per point), e.g. MPM particles.
    pub fn points<const D: usize>(x: &[SVector<f64, D>]) -> Self {
        Self {
            points: pad(x),
            nodes_per_cell: 1,
            connectivity: (0..x.len()).collect(),
            point_data: Vec::new(),
            cell_data: Vec::new(),
        }
    }

    /// Number of cells.
    pub fn num_cells(&self) -> usize {
        self.connectivity
            .len()
            .checked_div(self.nodes_per_cell)
            .unwrap_or(0)
    }

    /// Add a point field (builder style).
    pub fn with_point_field(mut self, f: Field) -> Self {
        self.point_data.push(f);
        self
    }

    /// Add a cell field (builder style).
    pub fn with_cell_field(mut self, f: Field) -> Self {
        self.cell_data.push(f);
        self
    }

    /// Check that every field has the right number of values.
    fn check(&self) -> Result<(), String> {
        let n = self.points.len();
        let m = self.num_cells();
        for f in &self.point_data {
            if f.values.len() != f.components * n {
                return Err(format!(
                    "point field `{}` has {} values for {n} points × {}",
                    f.name,
                    f.values.len(),
                    f.components
                ));
            }
        }
        for f in &self.cell_data {
            if f.values.len() != f.components * m {
                return Err(format!(
                    "cell field `{}` has {} values for {m} cells × {}",
                    f.name,
                    f.values.len(),
                    f.components
                ));
            }
        }
        if let Some(&bad) = self.connectivity.iter().find(|&&i| i >= n) {
            return Err(format!("connectivity references point {bad} of {n}"));
        }
        Ok(())
    }

    /// Write the grid.
    pub fn write(&self, path: &Path, encoding: Encoding) -> Result<(), FemError> {
        let io = |source| FemError::Io {
            path: path.to_path_buf(),
            source,
        };
        self.check().map_err(|message| FemError::MeshFile {
            path: path.to_path_buf(),
            line: 0,
            message,
        })?;
        let n = self.points.len();
        let m = self.num_cells();
        let cell_type = match self.nodes_per_cell {
            1 => VTK_VERTEX,
            3 => VTK_TRIANGLE,
            _ => VTK_TETRA,
        };
        let offsets: Vec<i64> = (1..=m).map(|c| (c * self.nodes_per_cell) as i64).collect();
        let conn: Vec<i64> = self.connectivity.iter().map(|&i| i as i64).collect();
        let types = vec![cell_type; m];
        let points: Vec<f64> = self.points.iter().flatten().copied().collect();

        // Arrays in file order: point data, cell data, points, connectivity, offsets, types.
        enum Arr<'a> {
            F(&'a [f64]),
            I(&'a [i64]),
            U(&'a [u8]),
        }
        let mut arrays: Vec<(String, usize, Arr)> = Vec::new();
        for f in &self.point_data {
            arrays.push((f.name.clone(), f.components, Arr::F(&f.values)));
        }
        for f in &self.cell_data {
            arrays.push((f.name.clone(), f.components, Arr::F(&f.values)));
        }
        arrays.push((String::new(), 3, Arr::F(&points)));
        arrays.push(("connectivity".into(), 1, Arr::I(&conn)));
        arrays.push(("offsets".into(), 1, Arr::I(&offsets)));
        arrays.push(("types".into(), 1, Arr::U(&types)));

        let mut xml = String::new();
        let mut blob: Vec<u8> = Vec::new();
        let mut tag = |xml: &mut String, name: &str, comps: usize, arr: &Arr| {
            let (ty, len_bytes) = match arr {
                Arr::F(v) => ("Float64", v.len() * 8),
                Arr::I(v) => ("Int64", v.len() * 8),
                Arr::U(v) => ("UInt8", v.len()),
            };
            let name_attr = if name.is_empty() {
                String::new()
            } else {
                format!(" Name=\"{}\"", escape(name))
            };
            match encoding {
                Encoding::Ascii => {
                    let _ = writeln!(
                        xml,
                        "<DataArray type=\"{ty}\"{name_attr} NumberOfComponents=\"{comps}\" format=\"ascii\">"
                    );
                    match arr {
                        Arr::F(v) => v.iter().for_each(|x| {
                            let _ = write!(xml, "{x:e} ");
                        }),
                        Arr::I(v) => v.iter().for_each(|x| {
                            let _ = write!(xml, "{x} ");
                        }),
                        Arr::U(v) => v.iter().for_each(|x| {
                            let _ = write!(xml, "{x} ");
                        }),
                    }
                    xml.push_str("\n</DataArray>\n");
                }
                Encoding::Binary => {
                    let _ = writeln!(
                        xml,
                        "<DataArray type=\"{ty}\"{name_attr} NumberOfComponents=\"{comps}\" format=\"appended\" offset=\"{}\"/>",
                        blob.len()
                    );
                    blob.extend_from_slice(&(len_bytes as u64).to_le_bytes());
                    match arr {
                        Arr::F(v) => v
                            .iter()
                            .for_each(|x| blob.extend_from_slice(&x.to_le_bytes())),
                        Arr::I(v) => v
                            .iter()
                            .for_each(|x| blob.extend_from_slice(&x.to_le_bytes())),
                        Arr::U(v) => blob.extend_from_slice(v),
                    }
                }
            }
        };
        xml.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n");
        let _ = writeln!(xml, "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{m}\">");
        let np = self.point_data.len();
        let nc = self.cell_data.len();
        xml.push_str("<PointData>\n");
        for (name, c, a) in &arrays[..np] {
            tag(&mut xml, name, *c, a);
        }
        xml.push_str("</PointData>\n<CellData>\n");
        for (name, c, a) in &arrays[np..np + nc] {
            tag(&mut xml, name, *c, a);
        }
        xml.push_str("</CellData>\n<Points>\n");
        let (name, c, a) = &arrays[np + nc];
        tag(&mut xml, name, *c, a);
        xml.push_str("</Points>\n<Cells>\n");
        for (name, c, a) in &arrays[np + nc + 1..] {
            tag(&mut xml, name, *c, a);
        }
        xml.push_str("</Cells>\n</Piece>\n</UnstructuredGrid>\n");
        // Written to a temporary name beside the target and renamed: a reader (ParaView
        // following a running simulation) never sees a half-written file, and a write that
        // fails (full disk) leaves no partial one behind.
        let tmp = path.with_extension("vtu.tmp");
        let write = || -> std::io::Result<()> {
            let mut file = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
            file.write_all(xml.as_bytes())?;
            if encoding == Encoding::Binary {
                file.write_all(b"<AppendedData encoding=\"raw\">\n_")?;
                file.write_all(&blob)?;
                file.write_all(b"\n</AppendedData>\n")?;
            }
            file.write_all(b"</VTKFile>\n")?;
            file.into_inner().map_err(|e| e.into_error())?;
            std::fs::rename(&tmp, path)
        };
        write().map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            io(e)
        })
    }

    /// Read a `.vtu` written by [`Vtu::write`] (either encoding).
    pub fn read(path: &Path) -> Result<Self, FemError> {
        let bytes = std::fs::read(path).map_err(|source| FemError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let bad = |message: String| FemError::MeshFile {
            path: path.to_path_buf(),
            line: 0,
            message,
        };
        // The XML part ends where the appended data begins.
        let marker = b"<AppendedData encoding=\"raw\">";
        let (xml_end, blob) = match find(&bytes, marker) {
            Some(i) => {
                let start = i + marker.len();
                let us = bytes[start..]
                    .iter()
                    .position(|&b| b == b'_')
                    .ok_or_else(|| bad("appended data has no `_` marker".into()))?;
                (i, &bytes[start + us + 1..])
            }
            None => (bytes.len(), &bytes[..0]),
        };
        let xml = std::str::from_utf8(&bytes[..xml_end])
            .map_err(|e| bad(format!("XML is not UTF-8: {e}")))?;
        let piece_start = xml.find("<Piece").ok_or_else(|| bad("no <Piece>".into()))?;
        let piece_tag = &xml[piece_start..xml[piece_start..].find('>').unwrap_or(0) + piece_start];
        let n: usize = attr(piece_tag, "NumberOfPoints")
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| bad("no NumberOfPoints".into()))?;
        let m: usize = attr(piece_tag, "NumberOfCells")
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| bad("no NumberOfCells".into()))?;
        let section = |name: &str| -> &str {
            let open = format!("<{name}>");
            let close = format!("</{name}>");
            match (xml.find(&open), xml.find(&close)) {
                (Some(a), Some(b)) if b > a => &xml[a + open.len()..b],
                _ => "",
            }
        };
        let pts = data_arrays(section("Points"), blob, &bad)?;
        let (_, _, pv) = pts
            .first()
            .ok_or_else(|| bad("no point coordinates".into()))?;
        if pv.len() != 3 * n {
            return Err(bad(format!("{} coordinates for {n} points", pv.len())));
        }
        let points: Vec<[f64; 3]> = pv.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let cells = data_arrays(section("Cells"), blob, &bad)?;
        let get = |k: &str| {
            cells
                .iter()
                .find(|(name, _, _)| name == k)
                .map(|(_, _, v)| v.clone())
        };
        let connectivity: Vec<usize> = get("connectivity")
            .unwrap_or_default()
            .iter()
            .map(|&v| v as usize)
            .collect();
        let offsets = get("offsets").unwrap_or_default();
        let nodes_per_cell = if m > 0 {
            offsets.first().copied().unwrap_or(0.0) as usize
        } else {
            0
        };
        let to_fields = |v: Vec<(String, usize, Vec<f64>)>| {
            v.into_iter()
                .map(|(name, components, values)| Field {
                    name,
                    components,
                    values,
                })
                .collect()
        };
        let out = Self {
            points,
            nodes_per_cell,
            connectivity,
            point_data: to_fields(data_arrays(section("PointData"), blob, &bad)?),
            cell_data: to_fields(data_arrays(section("CellData"), blob, &bad)?),
        };
        out.check().map_err(bad)?;
        Ok(out)
    }

    /// A field by name (point fields first, then cell fields).
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.point_data
            .iter()
            .chain(&self.cell_data)
            .find(|f| f.name == name)
    }
}

fn pad<const D: usize>(x: &[SVector<f64, D>]) -> Vec<[f64; 3]> {
    x.iter()
        .map(|p| std::array::from_fn(|a| if a < D { p[a] } else { 0.0 }))
        .collect()
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// A ParaView time series: `(time, file)` entries, rewritten after every frame.
#[derive(Clone, Debug)]
pub struct Pvd {
    path: PathBuf,
    entries: Vec<(f64, String, usize)>,
}

impl Pvd {
    /// A collection written to `path` (the frames' paths are stored relative to its directory).
    pub fn new(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
            entries: Vec::new(),
        }
    }

    /// Record a frame at `time` (a file in the same directory as the `.pvd`, or below it) as
    /// part `part` (several bodies per time) and rewrite the collection.
    pub fn add(&mut self, time: f64, file: &Path, part: usize) -> Result<(), FemError> {
        self.add_all([(time, file)], part)
    }

    /// Record several frames (`(time, file)`, as [`Pvd::add`] one) as part `part`, and
    /// rewrite the collection once.
    pub fn add_all<'a>(
        &mut self,
        frames: impl IntoIterator<Item = (f64, &'a Path)>,
        part: usize,
    ) -> Result<(), FemError> {
        for (time, file) in frames {
            let rel = self
                .path
                .parent()
                .and_then(|dir| file.strip_prefix(dir).ok())
                .unwrap_or(file);
            self.entries
                .push((time, rel.to_string_lossy().replace('\\', "/"), part));
        }
        self.write()
    }

    /// Number of frames recorded.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no frame is recorded.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn write(&self) -> Result<(), FemError> {
        let mut s = String::from(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n",
        );
        for (t, f, part) in &self.entries {
            let _ = writeln!(
                s,
                "<DataSet timestep=\"{t:e}\" part=\"{part}\" file=\"{}\"/>",
                escape(f)
            );
        }
        s.push_str("</Collection>\n</VTKFile>\n");
        // Write to a temporary file and rename, so the collection is never half-written.
        let tmp = self.path.with_extension("pvd.tmp");
        std::fs::write(&tmp, s)
            .and_then(|_| std::fs::rename(&tmp, &self.path))
            .map_err(|source| {
                let _ = std::fs::remove_file(&tmp);
                FemError::Io {
                    path: self.path.clone(),
                    source,
                }
            })
    }
}
