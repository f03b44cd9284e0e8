//! Pictures of a run: key frames as PNG and an animated GIF, drawn from the world itself.
//!
//! Particles are discs the size of their sampling spacing, coloured by von Mises stress (viridis,
//! one scale for particles and FEM cells that only grows during the run, so later frames are
//! comparable with earlier ones). FEM meshes are drawn cell by cell with their edges; fully
//! prescribed bodies (plates, moving boundaries) are grey. 2D level-set boundaries are shaded
//! where they are solid. 3D scenes are seen from a fixed orthographic camera (azimuth 35°,
//! elevation 25°; up is against gravity, or y, or the axis asked for): FEM boundary facets with Lambert shading and particles, painted back to front.
//!
//! The view is fixed over the run: the bounding box of every body at t = 0 with a margin.

use std::path::{Path, PathBuf};
use std::sync::Once;

use nalgebra::{SVector, Vector3};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};

use crate::error::SimError;
use crate::world::World;
use femp_fem::Hyperelastic;
use femp_fem::material::von_mises;

/// What to draw and how often.
#[derive(Clone, Debug)]
pub struct PictureOptions {
    /// Number of PNG key frames, evenly spaced in time from the start to the end (≥ 2).
    pub key_frames: usize,
    /// Number of GIF frames over the run (0: no GIF).
    pub gif_frames: usize,
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Delay between GIF frames (ms).
    pub gif_delay_ms: u32,
    /// 3D: the axis drawn upwards (0 = x, 1 = y, 2 = z); default: against gravity's largest
    /// component, or y without gravity.
    pub up: Option<usize>,
}

/// The most key frames [`Pictures`] draws.
pub const MAX_KEY_FRAMES: usize = 1000;
/// The most GIF frames [`Pictures`] draws.
pub const MAX_GIF_FRAMES: usize = 10_000;
/// The largest picture side (pixels): a frame is held in memory while it is drawn.
pub const MAX_SIDE: u32 = 8192;

impl Default for PictureOptions {
    fn default() -> Self {
        Self {
            key_frames: 6,
            gif_frames: 60,
            size: (640, 480),
            gif_delay_ms: 80,
            up: None,
        }
    }
}

/// Maps world coordinates to pixels.
#[derive(Clone, Debug)]
struct View {
    /// Camera axes (right, up, towards the viewer); in 2D the identity's first two columns.
    right: Vector3<f64>,
    up: Vector3<f64>,
    toward: Vector3<f64>,
    /// Projected lower-left corner and pixels per metre.
    origin: (f64, f64),
    scale: f64,
    size: (u32, u32),
    /// Header height in pixels (time label and colour bar).
    header: u32,
}

fn lift<const D: usize>(x: &SVector<f64, D>) -> Vector3<f64> {
    let mut p = Vector3::zeros();
    for k in 0..D.min(3) {
        p[k] = x[k];
    }
    p
}

impl View {
    fn new<const D: usize>(
        points: impl Iterator<Item = Vector3<f64>>,
        size: (u32, u32),
        up_axis: usize,
    ) -> Self {
        let (right, up, toward) = if D == 2 {
            (Vector3::x(), Vector3::y(), Vector3::z())
        } else {
            let (az, el) = (35f64.to_radians(), 25f64.to_radians());
            let axis = |k: usize| {
                let mut e = Vector3::zeros();
                e[k % 3] = 1.0;
                e
            };
            let (u, a, b) = (axis(up_axis), axis(up_axis + 1), axis(up_axis + 2));
            // Direction from the scene towards the camera (y up: a = z, b = x).
            let toward = b * (az.sin() * el.cos()) + u * el.sin() + a * (az.cos() * el.cos());
            let right = u.cross(&toward).normalize();
            let up = toward.cross(&right);
            (right, up, toward)
        };
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for p in points {
            let (u, v) = (p.dot(&right), p.dot(&up));
            lo = (lo.0.min(u), lo.1.min(v));
            hi = (hi.0.max(u), hi.1.max(v));
        }
        if !lo.0.is_finite() {
            lo = (-1.0, -1.0);
            hi = (1.0, 1.0);
        }
        let header = 28;
        let (w, h) = (size.0 as f64, (size.1 - header) as f64);
        let span = ((hi.0 - lo.0).max(1e-9), (hi.1 - lo.1).max(1e-9));
        let margin = 0.08;
        let scale = (w / (span.0 * (1.0 + 2.0 * margin))).min(h / (span.1 * (1.0 + 2.0 * margin)));
        // Centre the box.
        let origin = (
            0.5 * (lo.0 + hi.0) - 0.5 * w / scale,
            0.5 * (lo.1 + hi.1) - 0.5 * h / scale,
        );
        Self {
            right,
            up,
            toward,
            origin,
            scale,
            size,
            header,
        }
    }

    fn pixel(&self, p: &Vector3<f64>) -> (i32, i32) {
        let u = (p.dot(&self.right) - self.origin.0) * self.scale;
        let v = (p.dot(&self.up) - self.origin.1) * self.scale;
        (u.round() as i32, (self.size.1 as f64 - v).round() as i32)
    }

    /// World point of a pixel centre (2D only).
    fn world(&self, px: i32, py: i32) -> (f64, f64) {
        (
            self.origin.0 + (px as f64 + 0.5) / self.scale,
            self.origin.1 + (self.size.1 as f64 - py as f64 - 0.5) / self.scale,
        )
    }

    fn depth(&self, p: &Vector3<f64>) -> f64 {
        p.dot(&self.toward)
    }
}

/// Register the embedded DejaVu Sans (regular and bold) under the family names plotters asks
/// for, once per process: pictures and charts then need no system font libraries.
pub fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for family in ["sans-serif", "serif"] {
            let _ =
                plotters::style::register_font(family, FontStyle::Normal, dejavu::sans::regular());
            let _ = plotters::style::register_font(family, FontStyle::Bold, dejavu::sans::bold());
        }
    });
}

/// Key frames and a GIF of a run (see the module documentation).
pub struct Pictures {
    dir: PathBuf,
    opts: PictureOptions,
    view: View,
    duration: f64,
    stress_max: f64,
    keys_done: usize,
    gif_done: usize,
    gif: Option<Gif>,
    written: Vec<PathBuf>,
}

/// The animation: each frame drawn into one RGB buffer and encoded as it is drawn. The encoder
/// is owned here (plotters' GIF backend holds its buffer behind an `Rc`), so pictures — and a
/// recording with them — can move to the thread that steps the world.
struct Gif {
    encoder: gif::Encoder<std::io::BufWriter<std::fs::File>>,
    buffer: Vec<u8>,
    size: (u32, u32),
    /// Between frames, in hundredths of a second.
    delay: u16,
}

impl Gif {
    fn create(path: &Path, size: (u32, u32), delay_ms: u32) -> Result<Self, SimError> {
        let file = std::fs::File::create(path).map_err(|source| SimError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut encoder = gif::Encoder::new(
            std::io::BufWriter::new(file),
            size.0 as u16,
            size.1 as u16,
            &[],
        )
        .map_err(draw_err)?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(draw_err)?;
        Ok(Self {
            encoder,
            buffer: vec![0; 3 * size.0 as usize * size.1 as usize],
            size,
            delay: (delay_ms.saturating_add(5) / 10).min(u16::MAX as u32) as u16,
        })
    }

    /// Draw `scene` as the next frame.
    fn frame(
        &mut self,
        scene: &Snapshot,
        view: &View,
        stress_max: f64,
        t: f64,
    ) -> Result<(), SimError> {
        {
            let area = BitMapBackend::with_buffer(&mut self.buffer, self.size).into_drawing_area();
            scene.paint(&area, view, stress_max, t)?;
            area.present().map_err(draw_err)?;
        }
        let mut frame =
            gif::Frame::from_rgb_speed(self.size.0 as u16, self.size.1 as u16, &self.buffer, 10);
        frame.delay = self.delay;
        self.encoder.write_frame(&frame).map_err(draw_err)
    }

    /// Write the GIF's trailer and close it.
    fn close(self) -> Result<(), SimError> {
        self.encoder
            .into_inner()
            .and_then(|mut w| std::io::Write::flush(&mut w))
            .map_err(draw_err)
    }
}

fn draw_err(e: impl std::fmt::Display) -> SimError {
    SimError::Build {
        context: "drawing pictures".into(),
        message: e.to_string(),
    }
}

impl Pictures {
    /// Prepare pictures of `world` (at t = 0) into `dir` (`key_NN.png`, `animation.gif`) for a
    /// run of `duration` seconds.
    pub fn new<const D: usize>(
        world: &World<D>,
        dir: &Path,
        duration: f64,
        opts: PictureOptions,
    ) -> Result<Self, SimError> {
        let side = 64..=MAX_SIDE;
        if opts.key_frames < 2 && opts.key_frames != 0
            || opts.key_frames > MAX_KEY_FRAMES
            || opts.gif_frames > MAX_GIF_FRAMES
            || !side.contains(&opts.size.0)
            || !side.contains(&opts.size.1)
        {
            return Err(crate::error::invalid(
                "pictures",
                format!(
                    "need 0 or 2–{MAX_KEY_FRAMES} key frames, at most {MAX_GIF_FRAMES} GIF frames \
                     and 64 to {MAX_SIDE} pixels a side"
                ),
            ));
        }
        register_fonts();
        std::fs::create_dir_all(dir).map_err(|source| SimError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        let mut pts: Vec<Vector3<f64>> = Vec::new();
        if let Some(m) = &world.bodies.mpm {
            pts.extend(m.x.iter().map(lift));
        }
        for b in &world.bodies.fem {
            pts.extend(b.x.iter().map(lift));
        }
        let up = match opts.up {
            Some(k) if k < D => k,
            Some(k) => {
                return Err(crate::error::invalid(
                    "pictures.up",
                    format!("axis {k} does not exist in {D}D"),
                ));
            }
            None => {
                let g = &world.bodies.gravity;
                if g.norm() > 0.0 { g.iamax() } else { 1 }
            }
        };
        let view = View::new::<D>(pts.into_iter(), opts.size, up);
        let gif = if opts.gif_frames > 0 {
            Some(Gif::create(
                &dir.join("animation.gif"),
                opts.size,
                opts.gif_delay_ms,
            )?)
        } else {
            None
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            opts,
            view,
            duration,
            stress_max: 0.0,
            keys_done: 0,
            gif_done: 0,
            gif,
            written: Vec::new(),
        })
    }

    /// Draw whatever is due at the world's current time (call at t = 0 and after every step).
    pub fn update<const D: usize>(&mut self, world: &World<D>) -> Result<(), SimError> {
        let (t, duration) = (world.clock.time, self.duration);
        let due = move |k: usize, n: usize| -> bool {
            n > 0 && k < n && t + 1e-12 >= duration * k as f64 / (n.max(2) - 1) as f64
        };
        let key = due(self.keys_done, self.opts.key_frames);
        let gif = self.gif.is_some() && due(self.gif_done, self.opts.gif_frames);
        if !key && !gif {
            return Ok(());
        }
        let scene = Snapshot::of(world, &self.view);
        self.stress_max = self.stress_max.max(scene.stress_max);
        if key {
            self.write_key(&scene, t)?;
            // Skip key frames a long step jumped over.
            while due(self.keys_done, self.opts.key_frames) {
                self.keys_done += 1;
            }
        }
        if gif && let Some(g) = self.gif.as_mut() {
            g.frame(&scene, &self.view, self.stress_max, t)?;
            while due(self.gif_done, self.opts.gif_frames) {
                self.gif_done += 1;
            }
        }
        Ok(())
    }

    /// Write `scene` as the next key frame, `key_NN.png`.
    fn write_key(&mut self, scene: &Snapshot, t: f64) -> Result<(), SimError> {
        let path = self.dir.join(format!("key_{:02}.png", self.keys_done));
        {
            let area = BitMapBackend::new(&path, self.opts.size).into_drawing_area();
            scene.paint(&area, &self.view, self.stress_max, t)?;
            area.present().map_err(draw_err)?;
        }
        self.written.push(path);
        Ok(())
    }

    /// Draw `world` into an RGB buffer (row-major, 3 bytes per pixel, `size.0 × size.1`), for
    /// callers that want the picture without files.
    pub fn render_rgb<const D: usize>(&mut self, world: &World<D>) -> Result<Vec<u8>, SimError> {
        let (w, h) = self.opts.size;
        let mut buf = vec![0u8; 3 * w as usize * h as usize];
        let scene = Snapshot::of(world, &self.view);
        self.stress_max = self.stress_max.max(scene.stress_max);
        {
            let area = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            scene.paint(&area, &self.view, self.stress_max, world.clock.time)?;
            area.present().map_err(draw_err)?;
        }
        Ok(buf)
    }

    /// The pixel (column, row from the top) where the world point `x` is drawn.
    pub fn pixel<const D: usize>(&self, x: &SVector<f64, D>) -> (i32, i32) {
        self.view.pixel(&lift(x))
    }

    /// Stop without drawing anything more (an interrupted run): close the GIF if it holds a
    /// frame, else remove it (a GIF header alone is no picture). Returns every PNG written.
    pub fn abandon(mut self) -> Vec<PathBuf> {
        if let Some(g) = self.gif.take() {
            if self.gif_done > 0 {
                let _ = g.close();
            } else {
                drop(g);
                let _ = std::fs::remove_file(self.dir.join("animation.gif"));
            }
        }
        self.written
    }

    /// Draw the last state as the final key frame if the run ended early (failure,
    /// `max_steps`), and close the GIF. Returns every PNG written.
    pub fn finish<const D: usize>(mut self, world: &World<D>) -> Result<Vec<PathBuf>, SimError> {
        if self.opts.key_frames > 0 && self.keys_done < self.opts.key_frames {
            let scene = Snapshot::of(world, &self.view);
            self.stress_max = self.stress_max.max(scene.stress_max);
            self.write_key(&scene, world.clock.time)?;
        }
        if let Some(g) = self.gif.take() {
            g.close()?;
        }
        Ok(self.written)
    }
}

/// `c` with every channel multiplied by `f` (≤ 1: darker).
fn scaled(c: RGBColor, f: f64) -> RGBColor {
    RGBColor(
        (c.0 as f64 * f) as u8,
        (c.1 as f64 * f) as u8,
        (c.2 as f64 * f) as u8,
    )
}

/// Something to paint, with its depth (3D painter's order).
enum Prim {
    /// Filled polygon with its edges drawn darker; `stress` < 0 means grey (prescribed).
    Polygon {
        pts: Vec<(i32, i32)>,
        stress: f64,
        shade: f64,
    },
    /// A particle.
    Dot { at: (i32, i32), stress: f64 },
}

/// One frame's geometry in pixels.
struct Snapshot {
    prims: Vec<(f64, Prim)>,
    dot_radius: i32,
    stress_max: f64,
    /// 2D level sets, evaluated per pixel block.
    solid: Vec<(i32, i32)>,
    solid_block: i32,
}

impl Snapshot {
    fn of<const D: usize>(world: &World<D>, view: &View) -> Self {
        let mut prims = Vec::new();
        let mut stress_max = 0.0f64;
        let mut dot_radius = 1;
        if let Some(m) = &world.bodies.mpm {
            let n = m.x.len().max(1);
            let mean_vol = m.volume.iter().sum::<f64>() / n as f64;
            let spacing = mean_vol.powf(1.0 / D as f64);
            dot_radius = ((0.6 * spacing * view.scale).ceil() as i32).clamp(1, 12);
            for p in 0..m.x.len() {
                let mat = &m.bodies[m.body[p] as usize].material;
                let s = von_mises(&mat.first_piola(&m.f[p]), &m.f[p]);
                if s.is_finite() {
                    stress_max = stress_max.max(s);
                }
                let x = lift(&m.x[p]);
                prims.push((
                    view.depth(&x),
                    Prim::Dot {
                        at: view.pixel(&x),
                        stress: s,
                    },
                ));
            }
        }
        let light = Vector3::new(0.3, 1.0, 0.6).normalize();
        for b in &world.bodies.fem {
            let grey = b.fully_prescribed;
            let vm = if grey {
                Vec::new()
            } else {
                b.elastic.von_mises(&b.x)
            };
            if D == 2 {
                for (e, cell) in b.mesh.cells().iter().enumerate() {
                    let pts = cell[..3]
                        .iter()
                        .map(|&i| view.pixel(&lift(&b.x[i])))
                        .collect();
                    let s = if grey { -1.0 } else { vm[e] };
                    if s.is_finite() {
                        stress_max = stress_max.max(s);
                    }
                    prims.push((
                        -1.0,
                        Prim::Polygon {
                            pts,
                            stress: s,
                            shade: 1.0,
                        },
                    ));
                }
            } else {
                // Boundary facets; stress of a facet = stress of the cell it bounds is not
                // tracked by Boundary, so facets show the body's mean stress.
                let mean = if grey || vm.is_empty() {
                    -1.0
                } else {
                    vm.iter().sum::<f64>() / vm.len() as f64
                };
                if mean.is_finite() {
                    stress_max = stress_max.max(mean);
                }
                for f in b.boundary.facets() {
                    let p: Vec<Vector3<f64>> = f.iter().map(|&i| lift(&b.x[i])).collect();
                    let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
                    let len = n.norm();
                    if len == 0.0 || n.dot(&view.toward) <= 0.0 {
                        continue; // back face
                    }
                    let shade = 0.45 + 0.55 * (n / len).dot(&light).abs();
                    let c = (p[0] + p[1] + p[2]) / 3.0;
                    prims.push((
                        view.depth(&c),
                        Prim::Polygon {
                            pts: p.iter().map(|q| view.pixel(q)).collect(),
                            stress: mean,
                            shade,
                        },
                    ));
                }
            }
        }
        // Back to front; in 2D meshes (depth −1) go under particles (depth 0).
        prims.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut solid = Vec::new();
        let block = 2;
        if D == 2 && !world.bodies.boundaries.is_empty() {
            let (w, h) = (view.size.0 as i32, view.size.1 as i32);
            let mut py = view.header as i32;
            while py < h {
                let mut px = 0;
                while px < w {
                    let (x, y) = view.world(px, py);
                    let mut q = SVector::<f64, D>::zeros();
                    q[0] = x;
                    q[1] = y;
                    if world
                        .bodies
                        .boundaries
                        .iter()
                        .any(|ls| ls.eval(&q, world.clock.time).0 < 0.0)
                    {
                        solid.push((px, py));
                    }
                    px += block;
                }
                py += block;
            }
        }
        Self {
            prims,
            dot_radius,
            stress_max,
            solid,
            solid_block: block,
        }
    }

    fn paint<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        view: &View,
        stress_max: f64,
        t: f64,
    ) -> Result<(), SimError> {
        area.fill(&WHITE).map_err(draw_err)?;
        let ground = RGBColor(190, 170, 140);
        for &(px, py) in &self.solid {
            area.draw(&Rectangle::new(
                [(px, py), (px + self.solid_block, py + self.solid_block)],
                ground.filled(),
            ))
            .map_err(draw_err)?;
        }
        let colour = |s: f64, shade: f64| -> RGBColor {
            let c = if s < 0.0 {
                RGBColor(170, 170, 175)
            } else {
                let u = if stress_max > 0.0 {
                    (s / stress_max).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                ViridisRGB.get_color(u)
            };
            scaled(c, shade)
        };
        for (_, p) in &self.prims {
            match p {
                Prim::Polygon { pts, stress, shade } => {
                    let fill = colour(*stress, *shade);
                    area.draw(&Polygon::new(pts.clone(), fill.filled()))
                        .map_err(draw_err)?;
                    let mut ring = pts.clone();
                    ring.push(pts[0]);
                    area.draw(&PathElement::new(ring, scaled(fill, 0.6).stroke_width(1)))
                        .map_err(draw_err)?;
                }
                Prim::Dot { at, stress } => {
                    area.draw(&Circle::new(
                        *at,
                        self.dot_radius,
                        colour(*stress, 1.0).filled(),
                    ))
                    .map_err(draw_err)?;
                }
            }
        }
        // Header: time, colour bar.
        let h = view.header as i32;
        area.draw(&Rectangle::new(
            [(0, 0), (view.size.0 as i32, h)],
            WHITE.filled(),
        ))
        .map_err(draw_err)?;
        let small = view.size.0 < 500;
        let font = ("sans-serif", if small { 12 } else { 15 })
            .into_font()
            .color(&BLACK);
        area.draw(&Text::new(format!("t = {t:.4} s"), (6, 7), font.clone()))
            .map_err(draw_err)?;
        let (x0, bar_w) = if small { (96, 60) } else { (150, 160) };
        for k in 0..bar_w {
            let c = ViridisRGB.get_color(k as f64 / (bar_w - 1) as f64);
            area.draw(&Rectangle::new([(x0 + k, 8), (x0 + k + 1, 20)], c.filled()))
                .map_err(draw_err)?;
        }
        let label = if small {
            format!("0 … {stress_max:.2e} Pa")
        } else {
            format!("von Mises 0 … {stress_max:.3e} Pa")
        };
        area.draw(&Text::new(label, (x0 + bar_w + 6, 7), font))
            .map_err(draw_err)?;
        Ok(())
    }
}
