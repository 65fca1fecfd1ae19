//! A grey camera frame: 8- or 16-bit single-channel PNG, read with the
//! `image` crate, and what is wrong with a file that is not one.

use image::{DynamicImage, ImageFormat};

/// The PNG signature.
const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1A, b'\n'];
/// What `track` accepts, for error messages.
pub const ACCEPTED: &str = "8- or 16-bit greyscale PNG (colour type 0)";

/// Why bytes are not a usable frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FrameError {
    /// The file is empty.
    #[error("the file is empty (0 bytes); expected an {ACCEPTED}")]
    Empty,
    /// The bytes are not a PNG at all.
    #[error("not a PNG file (no PNG signature); expected an {ACCEPTED}")]
    NotPng,
    /// A PNG that cannot be decoded (truncated or corrupt).
    #[error("cannot decode the PNG (truncated or corrupt): {0}")]
    Decode(String),
    /// A PNG whose pixel format is not accepted.
    #[error("{found} PNG; expected an {ACCEPTED}")]
    Format {
        /// What the file holds, in words.
        found: String,
    },
    /// The frame's size differs from the camera's.
    #[error(
        "the image is {width}×{height} px but the camera is {camera_width}×{camera_height} px"
    )]
    SizeMismatch {
        /// Image width, px.
        width: u32,
        /// Image height, px.
        height: u32,
        /// Camera width, px.
        camera_width: u32,
        /// Camera height, px.
        camera_height: u32,
    },
    /// Pixel data that does not match the stated size or depth.
    #[error("{0}")]
    Inconsistent(String),
}

/// The width and height a PNG's header states, when the bytes start with
/// a PNG signature and an IHDR chunk.
pub fn png_size(bytes: &[u8]) -> Option<(u32, u32)> {
    if bytes.len() < 24 || bytes[..8] != PNG_SIGNATURE || &bytes[12..16] != b"IHDR" {
        return None;
    }
    let word =
        |at: usize| u32::from_be_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    Some((word(16), word(20)))
}

/// A grey frame: row-major samples with their bit depth.
#[derive(Debug, Clone, PartialEq)]
pub struct GreyFrame {
    width: u32,
    height: u32,
    bit_depth: u8,
    pixels: Vec<u16>,
}

impl GreyFrame {
    /// A frame from row-major samples of `bit_depth` (8 or 16) bits.
    pub fn new(
        width: u32,
        height: u32,
        bit_depth: u8,
        pixels: Vec<u16>,
    ) -> Result<Self, FrameError> {
        if bit_depth != 8 && bit_depth != 16 {
            return Err(FrameError::Inconsistent(format!(
                "bit depth must be 8 or 16, got {bit_depth}"
            )));
        }
        if width == 0 || height == 0 || pixels.len() != width as usize * height as usize {
            return Err(FrameError::Inconsistent(format!(
                "{} samples for a {width}×{height} frame",
                pixels.len()
            )));
        }
        if bit_depth == 8 && pixels.iter().any(|&v| v > 255) {
            return Err(FrameError::Inconsistent(
                "an 8-bit frame has a sample above 255".into(),
            ));
        }
        Ok(GreyFrame {
            width,
            height,
            bit_depth,
            pixels,
        })
    }

    /// Decodes PNG bytes of a `width`×`height` frame: a PNG whose header
    /// states another size is a [`FrameError::SizeMismatch`] before any
    /// pixel is decoded (so an 8000×8000 file costs no 195 MB), then as
    /// [`GreyFrame::from_png`].
    pub fn from_png_of_size(bytes: &[u8], width: u32, height: u32) -> Result<Self, FrameError> {
        if let Some((w, h)) = png_size(bytes) {
            if (w, h) != (width, height) {
                return Err(FrameError::SizeMismatch {
                    width: w,
                    height: h,
                    camera_width: width,
                    camera_height: height,
                });
            }
        }
        let frame = Self::from_png(bytes)?;
        frame.check_size(width, height)?;
        Ok(frame)
    }

    /// Decodes PNG bytes. Accepts [`ACCEPTED`]; a colour, alpha or
    /// 1/2/4-bit PNG is a [`FrameError::Format`] naming what it holds.
    pub fn from_png(bytes: &[u8]) -> Result<Self, FrameError> {
        if bytes.is_empty() {
            return Err(FrameError::Empty);
        }
        if bytes.len() < 8 || bytes[..8] != PNG_SIGNATURE {
            return Err(FrameError::NotPng);
        }
        // IHDR is the first chunk: length, "IHDR", width, height, bit
        // depth (byte 24), colour type (byte 25).
        if bytes.len() < 26 || &bytes[12..16] != b"IHDR" {
            return Err(FrameError::Decode("no IHDR header".into()));
        }
        let (depth, colour) = (bytes[24], bytes[25]);
        let colour_name = match colour {
            0 => "greyscale",
            2 => "RGB colour",
            3 => "palette colour",
            4 => "greyscale with alpha",
            6 => "RGBA colour",
            _ => "unknown colour type",
        };
        if colour != 0 || !(depth == 8 || depth == 16) {
            return Err(FrameError::Format {
                found: format!("{depth}-bit {colour_name}"),
            });
        }
        let image =
            image::load_from_memory_with_format(bytes, ImageFormat::Png).map_err(|e| match e {
                image::ImageError::Limits(limit) => FrameError::Inconsistent(format!(
                    "the PNG is larger than the decoder allows: {limit}"
                )),
                other => FrameError::Decode(other.to_string()),
            })?;
        let (width, height) = (image.width(), image.height());
        match image {
            DynamicImage::ImageLuma8(buffer) => GreyFrame::new(
                width,
                height,
                8,
                buffer.into_raw().into_iter().map(u16::from).collect(),
            ),
            DynamicImage::ImageLuma16(buffer) => {
                GreyFrame::new(width, height, 16, buffer.into_raw())
            }
            // A grey PNG with a transparency chunk decodes with alpha.
            DynamicImage::ImageLumaA8(_) | DynamicImage::ImageLumaA16(_) => {
                Err(FrameError::Format {
                    found: format!("{depth}-bit greyscale with a transparency chunk (tRNS)"),
                })
            }
            other => Err(FrameError::Format {
                found: format!("{:?}", other.color()),
            }),
        }
    }

    /// Encodes as a grey PNG of the frame's bit depth.
    pub fn to_png(&self) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut cursor = std::io::Cursor::new(&mut bytes);
        let result = if self.bit_depth == 8 {
            let data: Vec<u8> = self.pixels.iter().map(|&v| v as u8).collect();
            image::GrayImage::from_raw(self.width, self.height, data)
                .expect("the size was checked")
                .write_to(&mut cursor, ImageFormat::Png)
        } else {
            image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(
                self.width,
                self.height,
                self.pixels.clone(),
            )
            .expect("the size was checked")
            .write_to(&mut cursor, ImageFormat::Png)
        };
        result.expect("encoding a grey PNG into memory cannot fail");
        bytes
    }

    /// Width, px.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, px.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Bits per sample (8 or 16).
    pub fn bit_depth(&self) -> u8 {
        self.bit_depth
    }

    /// The largest sample value, `2^bit_depth − 1`.
    pub fn full_scale(&self) -> u16 {
        if self.bit_depth == 8 {
            255
        } else {
            u16::MAX
        }
    }

    /// Row-major samples.
    pub fn pixels(&self) -> &[u16] {
        &self.pixels
    }

    /// The sample at column `x`, row `y`.
    pub fn at(&self, x: u32, y: u32) -> u16 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Checks the frame's size against the camera's.
    pub fn check_size(&self, camera_width: u32, camera_height: u32) -> Result<(), FrameError> {
        if (self.width, self.height) != (camera_width, camera_height) {
            return Err(FrameError::SizeMismatch {
                width: self.width,
                height: self.height,
                camera_width,
                camera_height,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_every_refusal() {
        let frame = GreyFrame::new(3, 2, 16, vec![0, 1, 2, 3, 4, 65535]).unwrap();
        let png = frame.to_png();
        assert_eq!(GreyFrame::from_png(&png).unwrap(), frame);
        let eight = GreyFrame::new(2, 1, 8, vec![7, 255]).unwrap();
        assert_eq!(GreyFrame::from_png(&eight.to_png()).unwrap(), eight);
        assert_eq!(GreyFrame::from_png(&[]).unwrap_err(), FrameError::Empty);
        assert_eq!(
            GreyFrame::from_png(b"hello world").unwrap_err(),
            FrameError::NotPng
        );
        let truncated = GreyFrame::from_png(&png[..png.len() - 12]).unwrap_err();
        assert!(matches!(truncated, FrameError::Decode(_)), "{truncated}");
        let mut rgb = Vec::new();
        image::RgbImage::new(4, 4)
            .write_to(&mut std::io::Cursor::new(&mut rgb), ImageFormat::Png)
            .unwrap();
        let error = GreyFrame::from_png(&rgb).unwrap_err();
        assert_eq!(
            error.to_string(),
            "8-bit RGB colour PNG; expected an 8- or 16-bit greyscale PNG (colour type 0)"
        );
        assert!(GreyFrame::new(2, 2, 12, vec![0; 4]).is_err());
        assert!(GreyFrame::new(2, 2, 8, vec![0; 3]).is_err());
        assert!(GreyFrame::new(1, 1, 8, vec![256]).is_err());
        let mismatch = frame.check_size(1280, 720).unwrap_err();
        assert_eq!(
            mismatch.to_string(),
            "the image is 3×2 px but the camera is 1280×720 px"
        );
    }

    /// A 1-bit greyscale PNG (hand-made header) is refused by its header,
    /// before the decoder would silently expand it to 8 bits.
    #[test]
    fn low_bit_depths_are_refused() {
        let mut png = GreyFrame::new(2, 1, 8, vec![0, 255]).unwrap().to_png();
        png[24] = 1;
        let error = GreyFrame::from_png(&png).unwrap_err();
        assert!(
            error.to_string().starts_with("1-bit greyscale PNG"),
            "{error}"
        );
    }

    /// A header that states another size than the camera's is refused
    /// before a pixel is decoded: an 8000×8000 header on 2×1 px of data
    /// gives the size, not a decode error.
    #[test]
    fn a_frame_of_another_size_is_refused_by_its_header() {
        let mut png = GreyFrame::new(2, 1, 8, vec![0, 255]).unwrap().to_png();
        assert_eq!(png_size(&png), Some((2, 1)));
        png[16..20].copy_from_slice(&8000u32.to_be_bytes());
        png[20..24].copy_from_slice(&8000u32.to_be_bytes());
        let error = GreyFrame::from_png_of_size(&png, 1280, 1024).unwrap_err();
        assert_eq!(
            error.to_string(),
            "the image is 8000×8000 px but the camera is 1280×1024 px"
        );
        assert_eq!(png_size(b"not a png at all, but long enough"), None);
    }

    /// A grey PNG with a transparency chunk is named as such, not by the
    /// decoder's pixel type.
    #[test]
    fn a_grey_frame_with_a_transparency_chunk_is_named() {
        fn crc32(bytes: &[u8]) -> u32 {
            let mut crc = !0u32;
            for &byte in bytes {
                crc ^= u32::from(byte);
                for _ in 0..8 {
                    crc = (crc >> 1) ^ (0xEDB8_8320 & (crc & 1).wrapping_neg());
                }
            }
            !crc
        }
        let png = GreyFrame::new(2, 1, 8, vec![0, 255]).unwrap().to_png();
        // After the signature (8 bytes) and IHDR (25): a tRNS chunk that
        // makes level 0 transparent.
        let mut chunk = b"tRNS\x00\x00".to_vec();
        let crc = crc32(&chunk);
        chunk.extend_from_slice(&crc.to_be_bytes());
        let mut with_trns = png[..33].to_vec();
        with_trns.extend_from_slice(&2u32.to_be_bytes());
        with_trns.extend_from_slice(&chunk);
        with_trns.extend_from_slice(&png[33..]);
        let error = GreyFrame::from_png(&with_trns).unwrap_err();
        assert!(
            error
                .to_string()
                .starts_with("8-bit greyscale with a transparency chunk"),
            "{error}"
        );
    }
}
