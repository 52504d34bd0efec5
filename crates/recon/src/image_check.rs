//! Camera images checked before they become training or scoring targets (issue 28): an image
//! must be its camera's size (a 32x24 image for a 64x48 camera would be silently stretched) and a
//! JPEG must be whole (the decoder fills a file cut in half with grey and reports no error; a
//! complete JPEG has its end-of-image marker after the first scan's header, where no other
//! `FF D9` can occur because entropy-coded data stuffs every `FF` byte).

use crate::error::ReconError;
use std::path::Path;

/// Whether JPEG bytes reach their end-of-image marker. Walks the marker segments to the first
/// start-of-scan (so an embedded EXIF thumbnail's markers are skipped), then looks for `FF D9`.
pub fn jpeg_is_complete(b: &[u8]) -> bool {
    let mut i = 2;
    while i + 4 <= b.len() {
        if b[i] != 0xFF {
            return false;
        }
        let m = b[i + 1];
        if m == 0xFF {
            i += 1; // fill byte
            continue;
        }
        if m == 0x01 || (0xD0..=0xD8).contains(&m) {
            i += 2; // markers without a length
            continue;
        }
        let len = usize::from(u16::from_be_bytes([b[i + 2], b[i + 3]]));
        if m == 0xDA {
            let data = b.get(i + 2 + len..).unwrap_or(&[]);
            return data.windows(2).any(|w| w == [0xFF, 0xD9]);
        }
        i += 2 + len;
    }
    false
}

/// Decodes the image at `path` for camera `camera` of `width x height` pixels, refusing one of
/// another size or a truncated JPEG, naming the file.
pub fn open_camera_image(
    path: &Path,
    camera: &str,
    width: u32,
    height: u32,
) -> Result<image::DynamicImage, ReconError> {
    let bytes = std::fs::read(path).map_err(crate::error::io(path))?;
    let refuse = |detail: String| ReconError::Format { file: path.to_path_buf(), detail };
    if bytes.starts_with(&[0xFF, 0xD8]) && !jpeg_is_complete(&bytes) {
        return Err(refuse("truncated JPEG (no end-of-image marker after the image data)".into()));
    }
    let reader =
        image::ImageReader::new(std::io::Cursor::new(&bytes)).with_guessed_format().map_err(crate::error::io(path))?;
    let bad = |e: image::ImageError| ReconError::Image { file: path.to_path_buf(), detail: e.to_string() };
    let (w, h) = reader.into_dimensions().map_err(bad)?;
    if (w, h) != (width, height) {
        return Err(refuse(format!(
            "is {w}x{h} pixels, but camera {camera} is {width}x{height} (an image must be its camera's size)"
        )));
    }
    image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .map_err(crate::error::io(path))?
        .decode()
        .map_err(bad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jpeg(w: u32, h: u32) -> Vec<u8> {
        let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 7) as u8, (y * 5) as u8, 90]));
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90).encode_image(&img).unwrap();
        out
    }

    #[test]
    fn wrong_sizes_and_cut_jpegs_are_refused_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("000000_FRONT.jpg");
        let whole = jpeg(64, 48);
        assert!(jpeg_is_complete(&whole));
        std::fs::write(&p, &whole).unwrap();
        assert_eq!(open_camera_image(&p, "FRONT", 64, 48).unwrap().width(), 64);
        for (w, h) in [(32, 24), (20, 60)] {
            std::fs::write(&p, jpeg(w, h)).unwrap();
            let e = open_camera_image(&p, "FRONT", 64, 48).unwrap_err().to_string();
            assert!(e.contains(&format!("000000_FRONT.jpg: is {w}x{h} pixels, but camera FRONT is 64x48")), "{e}");
        }
        std::fs::write(&p, &whole[..whole.len() / 2]).unwrap();
        let e = open_camera_image(&p, "FRONT", 64, 48).unwrap_err().to_string();
        assert!(e.contains("000000_FRONT.jpg: truncated JPEG"), "{e}");
        assert!(!jpeg_is_complete(&whole[..whole.len() - 2]));
    }
}
