//! The sensor: a noise-free radiance image in, digital numbers out. Photon
//! shot noise (variance equal to the electron count, in its Gaussian
//! approximation), read noise, clipping at zero and full well, and
//! quantisation to 8 or 16 bits. Any number of realisations reuse one
//! noise-free render.
//!
//! **The noise draws.** Every pixel's standard normal draw is a function
//! of (seed, frame, realisation, pixel) alone: a counter-based generator,
//! the SplitMix64 finaliser of the row's key plus the pixel group's
//! counter times SplitMix64's increment, gives 64 bits for four
//! neighbouring pixels, and each 16 bits of them pick one of the
//! [`NORMAL_TABLE_SIZE`] equal-probability
//! bins of the standard normal, represented by its median (the inverse
//! normal CDF at the bin's middle). So the image does not depend on how
//! rows are shared among threads, and a draw costs a few instructions
//! rather than a stream cipher and a ziggurat. The table's draws reach
//! ±4.32σ and their variance is 1 − 2·10⁻⁵; a sensor's quantisation and
//! clipping discard finer detail of the distribution's tails.

use super::analysis::Radiance;
use super::config::Sensor;
use crate::identifiability::normal_upper_tail;
use rayon::prelude::*;
use std::sync::OnceLock;

/// Bins of the table-sampled standard normal (16 bits per draw).
pub const NORMAL_TABLE_SIZE: usize = 1 << 16;
/// Pixels that share one 64-bit counter-based draw.
const DRAWS_PER_WORD: usize = 4;
/// SplitMix64's increment (2⁶⁴ over the golden ratio, odd).
const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

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

/// The SplitMix64 finaliser: a bijection of 64-bit words whose outputs
/// for consecutive inputs pass as independent uniform bits.
fn finalise(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The standard normal's value at the middle (in probability) of each of
/// [`NORMAL_TABLE_SIZE`] equal-probability bins, ascending; built once.
fn normal_table() -> &'static [f32; NORMAL_TABLE_SIZE] {
    static TABLE: OnceLock<Box<[f32; NORMAL_TABLE_SIZE]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let half = NORMAL_TABLE_SIZE / 2;
        let density = |x: f64| (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
        // The upper half by Newton's method on the upper tail, each bin
        // starting from the one below it; the lower half by symmetry.
        let mut upper = Vec::with_capacity(half);
        let mut x = 0.0f64;
        for k in half..NORMAL_TABLE_SIZE {
            let tail = (NORMAL_TABLE_SIZE as f64 - k as f64 - 0.5) / NORMAL_TABLE_SIZE as f64;
            for _ in 0..8 {
                let step = (normal_upper_tail(x) - tail) / density(x);
                x += step;
                if step.abs() < 1e-10 * x.abs().max(1e-6) {
                    break;
                }
            }
            upper.push(x as f32);
        }
        let mut table: Box<[f32; NORMAL_TABLE_SIZE]> = vec![0f32; NORMAL_TABLE_SIZE]
            .into_boxed_slice()
            .try_into()
            .expect("a slice of the table's length");
        for (k, x) in upper.iter().enumerate() {
            table[half + k] = *x;
            table[half - 1 - k] = -x;
        }
        table
    })
}

/// The nearest integer to `level` in `[0, 65535]` (ties to even): added
/// to 2²³, where an `f32`'s unit in the last place is 1, the sum's low
/// mantissa bits are the rounded level. One add and a bit cast, so the
/// row loop vectorises.
fn round_level(level: f32) -> u16 {
    const SHIFT: f32 = 8_388_608.0;
    (level + SHIFT).to_bits() as u16
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
    let table = sensor.noise.as_ref().map(|_| normal_table());
    let mut values = vec![0u16; radiance.values.len()];
    values
        .par_chunks_mut(width.max(1))
        .zip(radiance.values.par_chunks(width.max(1)))
        .enumerate()
        .for_each_init(
            || vec![0f32; width],
            |draws, (row, (out, input))| match (&sensor.noise, table) {
                (Some(noise), Some(table)) => {
                    // The row's draws first (module docs), then the sensor's
                    // arithmetic over the row in a loop the compiler can
                    // vectorise.
                    let key = mix(&[seed, frame, realisation, row as u64]);
                    for (group, zs) in draws.chunks_mut(DRAWS_PER_WORD).enumerate() {
                        let bits =
                            finalise(key.wrapping_add((group as u64).wrapping_mul(GOLDEN_GAMMA)));
                        for (k, z) in zs.iter_mut().enumerate() {
                            *z = table[(bits >> (16 * k)) as u16 as usize];
                        }
                    }
                    let full_well = noise.full_well_electrons as f32;
                    let read_variance =
                        (noise.read_noise_electrons * noise.read_noise_electrons) as f32;
                    let scale = max_level / full_well;
                    for ((o, &v), &z) in out.iter_mut().zip(input).zip(draws.iter()) {
                        let electrons = v.max(0.0) * full_well;
                        let read = electrons + (electrons + read_variance).sqrt() * z;
                        *o = round_level((read * scale).clamp(0.0, max_level));
                    }
                }
                _ => {
                    for (o, &v) in out.iter_mut().zip(input) {
                        *o = round_level(v.clamp(0.0, 1.0) * max_level);
                    }
                }
            },
        );
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

    #[test]
    fn levels_round_to_the_nearest_integer() {
        for (level, expected) in [
            (0.0, 0),
            (0.49, 0),
            (0.51, 1),
            (254.6, 255),
            (65535.0, 65535),
        ] {
            assert_eq!(round_level(level), expected);
        }
    }

    #[test]
    fn the_normal_table_is_symmetric_sorted_and_has_unit_variance() {
        let table = normal_table();
        assert_eq!(table.len(), NORMAL_TABLE_SIZE);
        assert!(table.windows(2).all(|w| w[0] < w[1]));
        assert!(table.iter().zip(table.iter().rev()).all(|(a, b)| a == &-b));
        // The median of the top bin: Q(x) = 0.5 / 65536.
        assert!((f64::from(table[NORMAL_TABLE_SIZE - 1]) - 4.3249).abs() < 1e-3);
        let moments = table.iter().fold((0.0f64, 0.0f64), |(m, v), &x| {
            let x = f64::from(x);
            (m + x, v + x * x)
        });
        let n = NORMAL_TABLE_SIZE as f64;
        assert!((moments.0 / n).abs() < 1e-9);
        assert!(
            (moments.1 / n - 1.0 + 2.03e-5).abs() < 3e-6,
            "{}",
            moments.1 / n
        );
    }
}
