//! A grayscale PNG (deflate-compressed by the `png` crate) as base64 for a data URI.

use base64::Engine as _;

/// A `width` x `height` 8-bit grayscale PNG of `pixels` (row-major, one byte each).
pub fn gray_png(width: u32, height: u32, pixels: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width, height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::High);
    // Writing into a Vec fails only on a size mismatch, which the callers rule out.
    let mut w = enc.write_header().expect("a PNG header into memory");
    w.write_image_data(pixels)
        .expect("a PNG's pixels match its size");
    w.finish().expect("a PNG into memory");
    out
}

/// Standard base64 with padding.
pub fn base64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_meets_its_known_values() {
        assert_eq!(base64(b"Man"), "TWFu");
        assert_eq!(base64(b"Ma"), "TWE=");
        assert_eq!(base64(b"M"), "TQ==");
        assert_eq!(base64(b""), "");
    }

    #[test]
    fn a_png_decodes_to_its_pixels_and_is_compressed() {
        let (w, h) = (300u32, 400u32);
        // A field like the report's: smooth, with runs.
        let px: Vec<u8> = (0..w * h)
            .map(|i| ((i % w) / 4 + (i / w) / 8) as u8)
            .collect();
        let png = gray_png(w, h, &px);
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        assert!(
            png.len() < px.len() / 4,
            "{} bytes for {} pixels",
            png.len(),
            px.len()
        );
        let mut dec = png::Decoder::new(std::io::Cursor::new(&png))
            .read_info()
            .unwrap();
        let mut buf = vec![0; dec.output_buffer_size().unwrap()];
        let info = dec.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (w, h));
        assert_eq!(info.color_type, png::ColorType::Grayscale);
        assert_eq!(&buf[..info.buffer_size()], &px[..]);
    }
}
