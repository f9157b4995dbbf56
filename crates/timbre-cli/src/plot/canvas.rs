//! An RGB pixel buffer with the few drawing operations the plots need, written out as
//! a PNG file atomically (into a prepared `output::Output`, committed when complete).

use std::fs::File;
use std::io::{BufWriter, Write as _};

use crate::output::Output;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rgb(pub u8, pub u8, pub u8);

pub struct Canvas {
    width: usize,
    height: usize,
    /// Row-major RGB, three bytes a pixel.
    pixels: Vec<u8>,
}

impl Canvas {
    pub fn new(width: usize, height: usize, background: Rgb) -> Self {
        let mut canvas = Canvas {
            width,
            height,
            pixels: vec![0; width * height * 3],
        };
        canvas.fill(0, 0, width as i64, height as i64, background);
        canvas
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Sets one pixel; coordinates outside the canvas are ignored.
    pub fn set(&mut self, x: i64, y: i64, color: Rgb) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let i = (y as usize * self.width + x as usize) * 3;
        self.pixels[i..i + 3].copy_from_slice(&[color.0, color.1, color.2]);
    }

    #[cfg(test)]
    pub fn get(&self, x: usize, y: usize) -> Rgb {
        let i = (y * self.width + x) * 3;
        Rgb(self.pixels[i], self.pixels[i + 1], self.pixels[i + 2])
    }

    /// Fills the rectangle of `width` × `height` pixels whose top left is (`x`, `y`),
    /// clipped to the canvas.
    pub fn fill(&mut self, x: i64, y: i64, width: i64, height: i64, color: Rgb) {
        for yy in y.max(0)..(y + height).min(self.height as i64) {
            for xx in x.max(0)..(x + width).min(self.width as i64) {
                self.set(xx, yy, color);
            }
        }
    }

    /// A one-pixel rectangle drawn just outside the area (`x`, `y`, `width`, `height`),
    /// so the area itself stays untouched.
    pub fn frame(&mut self, x: i64, y: i64, width: i64, height: i64, color: Rgb) {
        self.fill(x - 1, y - 1, width + 2, 1, color);
        self.fill(x - 1, y + height, width + 2, 1, color);
        self.fill(x - 1, y, 1, height, color);
        self.fill(x + width, y, 1, height, color);
    }

    /// Writes the canvas as an 8-bit RGB PNG with `text` as tEXt chunks (keyword,
    /// value) into `output`, committed when complete; on failure the temporary file
    /// is removed and the target is left as it was.
    pub fn write_png(&self, mut output: Output, text: &[(String, String)]) -> Result<(), String> {
        self.encode(output.file(), text)
            .map_err(|e| format!("cannot write `{}`: {e}", output.path().display()))?;
        output.commit()
    }

    fn encode(
        &self,
        file: &mut File,
        text: &[(String, String)],
    ) -> Result<(), Box<dyn std::error::Error>> {
        let mut out = BufWriter::new(file);
        let mut encoder = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        for (keyword, value) in text {
            encoder.add_text_chunk(keyword.clone(), value.clone())?;
        }
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&self.pixels)?;
        writer.finish()?;
        out.flush()?;
        Ok(())
    }
}
