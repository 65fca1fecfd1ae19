//! The half-angle of the cone of viewing directions a marker is built for,
//! from the tilts and pans it will be seen at.

use super::geometry::DEFAULT_VIEW_CONE_DEG;
use crate::scenario::Range;

/// The view cone's half-angle: `--view-cone`, else the largest angle
/// between the main view and the view at a tilt t and pan p of the ranges
/// given (`acos(cos t · cos p)`, the camera turned about X then Y), else
/// [`DEFAULT_VIEW_CONE_DEG`] (`export`'s `--view-cone`, `--tilt`, `--pan`).
pub fn view_cone_deg(view_cone: Option<f64>, tilt: Option<&Range>, pan: Option<&Range>) -> f64 {
    if let Some(cone) = view_cone {
        return cone;
    }
    if tilt.is_none() && pan.is_none() {
        return DEFAULT_VIEW_CONE_DEG;
    }
    let zero = Range::single(0.0);
    let (tilt, pan) = (tilt.unwrap_or(&zero), pan.unwrap_or(&zero));
    let mut cone: f64 = 0.0;
    for t in &tilt.values {
        for p in &pan.values {
            let cosine = (t.to_radians().cos() * p.to_radians().cos()).clamp(-1.0, 1.0);
            cone = cone.max(cosine.acos().to_degrees());
        }
    }
    // acos(cos 25°) is 25.000000000000004°: whole nanodegrees read better.
    (cone * 1e9).round() / 1e9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_from_ranges_or_given_or_default() {
        assert_eq!(view_cone_deg(Some(12.5), None, None), 12.5);
        assert_eq!(view_cone_deg(None, None, None), DEFAULT_VIEW_CONE_DEG);
        let tilt: Range = "-25,10".parse().unwrap();
        assert_eq!(view_cone_deg(None, Some(&tilt), None), 25.0);
        let pan: Range = "0,30".parse().unwrap();
        let both = view_cone_deg(None, Some(&tilt), Some(&pan));
        let expected = (25f64.to_radians().cos() * 30f64.to_radians().cos())
            .acos()
            .to_degrees();
        assert!((both - expected).abs() < 1e-9, "{both} {expected}");
    }
}
