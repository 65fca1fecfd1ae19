//! The chain the search's `crlb` term scores (`--chain`): what stands
//! between a layout and the pose a user reads, besides the image noise.

use crate::camera::Camera;
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use std::str::FromStr;

/// The chain the objective scores: what stands between the layout and
/// the pose a user reads, besides the image noise.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Chain {
    /// The part is the layout, read as `observation` says (with ellipse
    /// centres, the `crlb` term carries their pose bias).
    #[default]
    Ideal,
    /// A part printed with every centre coordinate off by `sigma_mm`, read
    /// as `track` reads it: projected centres, no ellipse bias; the `crlb`
    /// term adds the part's pose covariance
    /// ([`crate::error_model::budget`]).
    Printed {
        /// σ per coordinate, mm.
        sigma_mm: f64,
    },
    /// A printed part characterised from the default capture plan
    /// ([`crate::characterise::plan`]) at `sigma_px` of centre noise, read
    /// as projected centres; the `crlb` term adds the pose covariance of
    /// the characterised centres' remaining error.
    Characterised {
        /// Centre noise of the capture, px per axis.
        sigma_px: f64,
    },
}

impl Chain {
    /// Each centre's covariance, mm², for a layout of `points`, or `None`
    /// for the ideal chain; `Some(None)` when the capture plan cannot
    /// characterise the layout.
    pub(super) fn part_covariances(
        &self,
        points: &[Vector3<f64>],
        sphere_diameter_mm: f64,
        camera: &Camera,
        depth_range_mm: (f64, f64),
    ) -> Option<Option<Vec<Matrix3<f64>>>> {
        match *self {
            Chain::Ideal => None,
            Chain::Printed { sigma_mm } => Some(Some(vec![
                Matrix3::identity()
                    * (sigma_mm * sigma_mm);
                points.len()
            ])),
            Chain::Characterised { sigma_px } => {
                let layout = crate::layout::Layout {
                    name: "candidate".into(),
                    points: points
                        .iter()
                        .enumerate()
                        .map(|(i, p)| crate::layout::LayoutPoint::new(format!("P{i}"), *p))
                        .collect(),
                    sphere_diameter_mm,
                    family: None,
                    provenance: None,
                };
                Some(crate::characterise::plan::predicted_covariances(
                    &layout,
                    camera,
                    depth_range_mm.0,
                    depth_range_mm.1,
                    sigma_px,
                ))
            }
        }
    }

    /// How reports name it.
    pub fn describe(&self) -> String {
        match self {
            Chain::Ideal => "ideal (the part is the layout)".into(),
            Chain::Printed { sigma_mm } => {
                format!("printed (σ {sigma_mm} mm per centre coordinate), read as projected centres")
            }
            Chain::Characterised { sigma_px } => format!(
                "printed and characterised from the default capture plan ({sigma_px} px centre noise), read as projected centres"
            ),
        }
    }
}

/// Default σ of a printed part's centres, mm per coordinate (an FDM or SLA
/// printer's ±0.1 mm).
pub const DEFAULT_PRINTED_SIGMA_MM: f64 = 0.1;

impl FromStr for Chain {
    type Err = String;

    /// `ideal`, `printed[:SIGMA_MM]` or `characterised[:SIGMA_PX]`.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let (kind, value) = match text.split_once(':') {
            Some((kind, value)) => (kind, Some(value)),
            None => (text, None),
        };
        let number = |default: f64, unit: &str| -> Result<f64, String> {
            let Some(value) = value else {
                return Ok(default);
            };
            match value.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
                _ => Err(format!(
                    "the chain's σ must be a positive number of {unit}, got '{value}'"
                )),
            }
        };
        match kind.trim() {
            "ideal" if value.is_none() => Ok(Chain::Ideal),
            "printed" => Ok(Chain::Printed {
                sigma_mm: number(DEFAULT_PRINTED_SIGMA_MM, "mm")?,
            }),
            "characterised" | "characterized" => Ok(Chain::Characterised {
                sigma_px: number(crate::characterise::plan::DEFAULT_PLAN_SIGMA_PX, "px")?,
            }),
            _ => Err(format!(
                "unknown chain '{text}'; use ideal, printed[:SIGMA_MM] or characterised[:SIGMA_PX]"
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_parse_and_refuse_with_the_reason() {
        assert_eq!("ideal".parse::<Chain>().unwrap(), Chain::Ideal);
        assert_eq!(
            "printed".parse::<Chain>().unwrap(),
            Chain::Printed {
                sigma_mm: DEFAULT_PRINTED_SIGMA_MM
            }
        );
        assert_eq!(
            "printed:0.2".parse::<Chain>().unwrap(),
            Chain::Printed { sigma_mm: 0.2 }
        );
        assert_eq!(
            "characterised:0.05".parse::<Chain>().unwrap(),
            Chain::Characterised { sigma_px: 0.05 }
        );
        assert_eq!(
            "printed:-1".parse::<Chain>().unwrap_err(),
            "the chain's σ must be a positive number of mm, got '-1'"
        );
        assert!("ideal:3"
            .parse::<Chain>()
            .unwrap_err()
            .starts_with("unknown chain"));
        assert!("cast"
            .parse::<Chain>()
            .unwrap_err()
            .starts_with("unknown chain"));
    }
}
