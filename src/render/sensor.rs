//! The sensor: a noise-free radiance image in, digital numbers out. Photon
//! shot noise (variance equal to the electron count, in its Gaussian
//! approximation), read noise, clipping at zero and full well, and
//! quantisation to 8 or 16 bits. Any number of realisations reuse one
//! noise-free render.
//!
//! Every row draws from its own ChaCha8 stream, seeded from (seed, frame,
//! realisation, row), so the image does not depend on how rows are shared
//! among threads.

use super::analysis::Radiance;
use super::config::Sensor;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// A quantised grey image, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Digital {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// 8 or 16.
    pub bit_depth: u8,
    /// Digital numbers, `0..2^bit_depth`.
    pub values: Vec<u16>,
}

/// One 64-bit seed from several (SplitMix64 finaliser over their sum).
fn mix(words: &[u64]) -> u64 {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for &w in words {
        state = state.wrapping_add(w).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        state ^= state >> 31;
        state = state.wrapping_mul(0x94D0_49BB_1331_11EB);
        state ^= state >> 29;
    }
    state
}

/// The sensor's reading of `radiance` for realisation `realisation` of
/// frame `frame` (module docs).
pub fn expose(
    radiance: &Radiance,
    sensor: &Sensor,
    seed: u64,
    frame: u64,
    realisation: u64,
) -> Digital {
    let max_level = ((1u32 << sensor.bit_depth) - 1) as f32;
    let width = radiance.width;
    let mut values = vec![0u16; radiance.values.len()];
    values
        .par_chunks_mut(width.max(1))
        .zip(radiance.values.par_chunks(width.max(1)))
        .enumerate()
        .for_each(|(row, (out, input))| match &sensor.noise {
            None => {
                for (o, &v) in out.iter_mut().zip(input) {
                    *o = (v.clamp(0.0, 1.0) * max_level).round() as u16;
                }
            }
            Some(noise) => {
                let mut rng =
                    ChaCha8Rng::seed_from_u64(mix(&[seed, frame, realisation, row as u64]));
                let full_well = noise.full_well_electrons as f32;
                let read_variance =
                    (noise.read_noise_electrons * noise.read_noise_electrons) as f32;
                let scale = max_level / full_well;
                for (o, &v) in out.iter_mut().zip(input) {
                    let electrons = v.max(0.0) * full_well;
                    let z: f32 = StandardNormal.sample(&mut rng);
                    let read = electrons + (electrons + read_variance).sqrt() * z;
                    *o = (read * scale).clamp(0.0, max_level).round() as u16;
                }
            }
        });
    Digital {
        width,
        height: radiance.height,
        bit_depth: sensor.bit_depth,
        values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::config::Noise;

    fn flat(value: f32) -> Radiance {
        Radiance {
            width: 200,
            height: 100,
            values: vec![value; 20_000],
        }
    }

    #[test]
    fn noise_free_exposure_quantises_and_clips() {
        let sensor = Sensor {
            bit_depth: 8,
            noise: None,
        };
        let image = expose(&flat(0.5), &sensor, 1, 0, 0);
        assert!(image.values.iter().all(|&v| v == 128));
        assert!(expose(&flat(1.7), &sensor, 1, 0, 0)
            .values
            .iter()
            .all(|&v| v == 255));
    }

    #[test]
    fn the_noise_has_the_shot_and_read_variance_and_is_seeded() {
        let sensor = Sensor {
            bit_depth: 16,
            noise: Some(Noise {
                full_well_electrons: 10_000.0,
                read_noise_electrons: 20.0,
            }),
        };
        let image = expose(&flat(0.25), &sensor, 3, 1, 2);
        let dn_per_electron = 65535.0 / 10_000.0;
        let values: Vec<f64> = image
            .values
            .iter()
            .map(|&v| v as f64 / dn_per_electron)
            .collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let variance =
            values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (values.len() - 1) as f64;
        // 2500 e⁻ of signal: variance 2500 + 400; 20 000 pixels give the
        // variance to about 1 %.
        assert!((mean - 2500.0).abs() < 2.0, "mean {mean}");
        assert!(
            (variance / 2900.0 - 1.0).abs() < 0.05,
            "variance {variance}"
        );
        assert_eq!(image, expose(&flat(0.25), &sensor, 3, 1, 2));
        assert_ne!(image, expose(&flat(0.25), &sensor, 3, 1, 3));
    }
}
