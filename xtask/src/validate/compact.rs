//! Smaller images for the committed report: a chart or picture is re-encoded as an indexed PNG
//! of at most 256 colours — exactly when it has no more (most pictures), through NeuQuant
//! (`color_quant`) when it has more (anti-aliased chart lines have ~2 000). The run's own
//! output keeps the full-colour originals and the SVGs.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{Context, Result};

/// Decode `src` (8-bit RGB or RGBA) into RGBA pixels and its size.
fn decode(src: &Path) -> Result<(Vec<u8>, u32, u32)> {
    let file = std::fs::File::open(src).with_context(|| format!("opening {}", src.display()))?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    // Palettes (and transparency) expanded to RGB(A).
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder
        .read_info()
        .with_context(|| format!("reading {}", src.display()))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf)?;
    anyhow::ensure!(
        info.bit_depth == png::BitDepth::Eight,
        "{}: {:?}-bit PNG (expected 8)",
        src.display(),
        info.bit_depth
    );
    let rgba = match info.color_type {
        png::ColorType::Rgba => buf[..info.buffer_size()].to_vec(),
        png::ColorType::Rgb => buf[..info.buffer_size()]
            .chunks_exact(3)
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        other => anyhow::bail!("{}: {other:?} PNG (expected RGB or RGBA)", src.display()),
    };
    Ok((rgba, info.width, info.height))
}

/// Palette (RGBA) and one index per pixel: exact if the image has ≤ 256 colours.
fn quantise(rgba: &[u8]) -> (Vec<[u8; 4]>, Vec<u8>) {
    let mut exact: HashMap<[u8; 4], u8> = HashMap::new();
    let mut palette = Vec::new();
    for c in rgba.chunks_exact(4) {
        let c = [c[0], c[1], c[2], c[3]];
        if let std::collections::hash_map::Entry::Vacant(e) = exact.entry(c) {
            if palette.len() == 256 {
                palette.clear();
                break;
            }
            e.insert(palette.len() as u8);
            palette.push(c);
        }
    }
    if !palette.is_empty() {
        let idx = rgba
            .chunks_exact(4)
            .map(|c| exact[&[c[0], c[1], c[2], c[3]]])
            .collect();
        return (palette, idx);
    }
    let nq = color_quant::NeuQuant::new(10, 256, rgba);
    let palette = nq
        .color_map_rgba()
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    // Charts repeat few colours over many pixels: look each one up once.
    let mut memo: HashMap<[u8; 4], u8> = HashMap::new();
    let idx = rgba
        .chunks_exact(4)
        .map(|c| {
            let c = [c[0], c[1], c[2], c[3]];
            *memo.entry(c).or_insert_with(|| nq.index_of(&c) as u8)
        })
        .collect();
    (palette, idx)
}

/// Write `src` as an indexed PNG to `dst`.
pub fn compact_png(src: &Path, dst: &Path) -> Result<()> {
    let (rgba, w, h) = decode(src)?;
    let (palette, idx) = quantise(&rgba);
    let file = std::fs::File::create(dst).with_context(|| format!("writing {}", dst.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Best);
    enc.set_palette(
        palette
            .iter()
            .flat_map(|c| [c[0], c[1], c[2]])
            .collect::<Vec<u8>>(),
    );
    if palette.iter().any(|c| c[3] != 255) {
        enc.set_trns(palette.iter().map(|c| c[3]).collect::<Vec<u8>>());
    }
    let mut writer = enc.write_header()?;
    writer.write_image_data(&idx)?;
    writer.finish()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_rgb(path: &Path, w: u32, h: u32, px: impl Fn(u32, u32) -> [u8; 3]) {
        let file = std::fs::File::create(path).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let data: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .flat_map(|(x, y)| px(x, y))
            .collect();
        enc.write_header().unwrap().write_image_data(&data).unwrap();
    }

    /// Few colours: the indexed copy decodes to exactly the same pixels.
    #[test]
    fn few_colours_round_trip_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
        write_rgb(&a, 40, 30, |x, y| {
            [(x % 7 * 30) as u8, (y % 5 * 50) as u8, 200]
        });
        compact_png(&a, &b).unwrap();
        assert_eq!(decode(&a).unwrap(), decode(&b).unwrap());
    }

    /// Many colours (a smooth gradient, ~20 000): quantised, each channel within a small
    /// error, and the file smaller.
    #[test]
    fn many_colours_are_quantised_closely() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
        write_rgb(&a, 160, 128, |x, y| {
            [x as u8, (y * 2) as u8, ((x + y) / 2) as u8]
        });
        compact_png(&a, &b).unwrap();
        let (pa, pb) = (decode(&a).unwrap().0, decode(&b).unwrap().0);
        let mean = pa
            .iter()
            .zip(&pb)
            .map(|(x, y)| (*x as f64 - *y as f64).abs())
            .sum::<f64>()
            / pa.len() as f64;
        assert!(mean < 6.0, "mean channel error {mean}");
        assert!(std::fs::metadata(&b).unwrap().len() < std::fs::metadata(&a).unwrap().len());
    }
}
