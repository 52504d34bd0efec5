//! An 8-bit RGB picture that layouts paste camera views and insets into, and that encoders take
//! as one video frame (row-major, 3 bytes a pixel, no padding: ffmpeg's `rgb24`).

use crate::RenderError;
use std::path::Path;

#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<u8>,
}

impl Canvas {
    pub fn new(width: usize, height: usize, fill: [u8; 3]) -> Self {
        Canvas { width, height, rgb: fill.iter().copied().cycle().take(width * height * 3).collect() }
    }

    /// A canvas from a drawn view's linear colours (clamped to [0, 1]).
    pub fn from_rgb_f64(width: usize, height: usize, rgb: &[[f64; 3]]) -> Self {
        Canvas { width, height, rgb: recon::view::to_rgb8(rgb) }
    }

    /// Copies `src` with its top-left corner at (`x`, `y`); what falls outside is cut.
    pub fn blit(&mut self, src: &Canvas, x: usize, y: usize) {
        let w = src.width.min(self.width.saturating_sub(x));
        for row in 0..src.height.min(self.height.saturating_sub(y)) {
            let d = ((y + row) * self.width + x) * 3;
            let s = row * src.width * 3;
            self.rgb[d..d + w * 3].copy_from_slice(&src.rgb[s..s + w * 3]);
        }
    }

    /// A one-pixel frame of `colour` around the rectangle (`x`, `y`, `w`, `h`).
    pub fn outline(&mut self, x: usize, y: usize, w: usize, h: usize, colour: [u8; 3]) {
        let mut put = |px: usize, py: usize| {
            if px < self.width && py < self.height {
                let i = (py * self.width + px) * 3;
                self.rgb[i..i + 3].copy_from_slice(&colour);
            }
        };
        for px in x..x + w {
            put(px, y);
            put(px, y + h.saturating_sub(1));
        }
        for py in y..y + h {
            put(x, py);
            put(x + w.saturating_sub(1), py);
        }
    }

    /// The same picture grown by at most one pixel right and down so both sides are even
    /// (H.264 in 4:2:0 needs even sizes).
    pub fn padded_even(&self) -> Canvas {
        let (w, h) = (self.width + self.width % 2, self.height + self.height % 2);
        if (w, h) == (self.width, self.height) {
            return self.clone();
        }
        let mut c = Canvas::new(w, h, [0, 0, 0]);
        c.blit(self, 0, 0);
        c
    }

    pub fn save_png(&self, path: &Path) -> Result<(), RenderError> {
        let img = image::RgbImage::from_raw(self.width as u32, self.height as u32, self.rgb.clone())
            .ok_or_else(|| RenderError::io(path, "canvas buffer size mismatch"))?;
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .map_err(|e| RenderError::io(path, e))?;
        scene::write_file_atomic(path, &png)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blit_cuts_at_the_edges_and_padding_keeps_the_picture() {
        let mut big = Canvas::new(5, 3, [0, 0, 0]);
        let small = Canvas::new(3, 2, [9, 9, 9]);
        big.blit(&small, 3, 2);
        assert_eq!(&big.rgb[(2 * 5 + 3) * 3..(2 * 5 + 5) * 3], &[9; 6]);
        assert_eq!(&big.rgb[..3], &[0, 0, 0]);
        let even = big.padded_even();
        assert_eq!((even.width, even.height), (6, 4));
        assert_eq!(&even.rgb[(2 * 6 + 3) * 3..(2 * 6 + 5) * 3], &[9; 6]);
    }
}
