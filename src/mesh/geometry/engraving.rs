//! A part's number engraved into its base plate, so that the parts of a
//! marker set are not swapped on the bench.
//!
//! The digits are a seven-segment stroke font: each stroke a round-bottomed
//! groove (a capsule whose cross-section meets the plate's face at the
//! stroke width and reaches [`ENGRAVING_DEPTH_MM`] below it), subtracted
//! from the solid's signed distance with a rounded rim. The grooves are cut
//! into the plate's face opposite the bed ([`Marker::down`]): for the
//! printable structure that is the face towards the camera, behind every
//! sphere, so the engraving removes material and adds no occluder; the
//! groove walls face up as printed, so it adds no overhang either.
//!
//! **Sizes.** The stroke width at the face is the larger of the minimum
//! printable feature and twice the depth (a half-round groove); a digit is
//! four stroke widths wide and seven high, so the land between two strokes
//! and the openings inside 0, 6, 8 and 9 are two stroke widths, again at
//! least the minimum feature. Digits sit two stroke widths apart.
//!
//! **Placement.** The text goes where no support lands: every candidate
//! position on a [`PLACEMENT_STEP_MM`] grid over the face (inside its
//! rounded rim by the minimum feature) is tried, and one is kept whose
//! grooves keep the minimum feature clear of every strut's surface grown
//! by its fillet, of every hole's rim and of every sphere; among those,
//! positions not behind a sphere in the main view come first, then the
//! one farthest from any part. When none fits, the plate is lengthened on
//! one side by the text's size plus the margins (the supports are not
//! moved) and the search runs again on the new strip.

use super::*;

/// Depth of the engraving below the plate's face, mm.
pub const ENGRAVING_DEPTH_MM: f64 = 0.6;
/// Grid step of the search for a place on the face, mm.
pub const PLACEMENT_STEP_MM: f64 = 0.5;
/// A digit's width, in stroke widths.
const DIGIT_WIDTH_STROKES: f64 = 4.0;
/// A digit's height, in stroke widths.
const DIGIT_HEIGHT_STROKES: f64 = 7.0;
/// Space between two digits, in stroke widths.
const DIGIT_SPACING_STROKES: f64 = 2.0;
/// Rim rounding of a groove, in stroke widths.
const RIM_BLEND_STROKES: f64 = 0.25;
/// Spacing of the points along each stroke tested for clearance, mm.
const STROKE_SAMPLE_MM: f64 = 0.25;

/// The engraved number of a part: the text, the groove's sizes and where
/// its strokes lie, marker frame, mm.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Engraving {
    /// The digits engraved.
    pub text: String,
    /// Depth of the grooves below the face, mm.
    pub depth_mm: f64,
    /// Width of a groove where it meets the face, mm.
    pub stroke_mm: f64,
    /// Radius of the grooves' round bottom, mm.
    pub groove_radius_mm: f64,
    /// Rounding of the grooves' rims, mm.
    pub rim_blend_mm: f64,
    /// Unit outward normal of the engraved face.
    pub normal: Vector3<f64>,
    /// The face's level: `p · normal` on it, mm.
    pub face_level_mm: f64,
    /// Reading direction of the text on the face (unit).
    pub right: Vector3<f64>,
    /// The text's up direction on the face (unit).
    pub up: Vector3<f64>,
    /// Lower left corner of the text's box on the face, mm.
    pub origin: Vector3<f64>,
    /// Width and height of the text's box, mm.
    pub size_mm: [f64; 2],
    /// Whether the plate was lengthened to make room for it.
    pub plate_grown: bool,
    /// The grooves' axes (segments), mm.
    pub strokes: Vec<(Vector3<f64>, Vector3<f64>)>,
}

/// Segments of a seven-segment digit: a top, b upper right, c lower right,
/// d bottom, e lower left, f upper left, g middle.
fn segments(digit: char) -> Option<&'static [u8]> {
    Some(match digit {
        '0' => b"abcdef",
        '1' => b"bc",
        '2' => b"abged",
        '3' => b"abgcd",
        '4' => b"fgbc",
        '5' => b"afgcd",
        '6' => b"afgedc",
        '7' => b"abc",
        '8' => b"abcdefg",
        '9' => b"abcdfg",
        _ => return None,
    })
}

/// The stroke width at the face for a minimum feature and a depth.
pub fn stroke_width_mm(min_feature_mm: f64, depth_mm: f64) -> f64 {
    min_feature_mm.max(2.0 * depth_mm)
}

/// Width and height of `text` in strokes of width `stroke`, mm.
fn text_size(text: &str, stroke: f64) -> [f64; 2] {
    let n = text.chars().count() as f64;
    [
        stroke * (n * DIGIT_WIDTH_STROKES + (n - 1.0).max(0.0) * DIGIT_SPACING_STROKES),
        stroke * DIGIT_HEIGHT_STROKES,
    ]
}

/// The strokes of `text` as 2-D segments in the text box (x right, y up,
/// origin at the lower left), mm.
fn text_strokes(text: &str, stroke: f64) -> Vec<([f64; 2], [f64; 2])> {
    let (w, h) = (stroke * DIGIT_WIDTH_STROKES, stroke * DIGIT_HEIGHT_STROKES);
    let mut out = Vec::new();
    for (k, digit) in text.chars().enumerate() {
        let x = k as f64 * stroke * (DIGIT_WIDTH_STROKES + DIGIT_SPACING_STROKES);
        let (x0, x1) = (x + 0.5 * stroke, x + w - 0.5 * stroke);
        let (y0, ym, y1) = (0.5 * stroke, 0.5 * h, h - 0.5 * stroke);
        for segment in segments(digit).unwrap_or(&[]) {
            out.push(match segment {
                b'a' => ([x0, y1], [x1, y1]),
                b'b' => ([x1, ym], [x1, y1]),
                b'c' => ([x1, y0], [x1, ym]),
                b'd' => ([x0, y0], [x1, y0]),
                b'e' => ([x0, y0], [x0, ym]),
                b'f' => ([x0, ym], [x0, y1]),
                _ => ([x0, ym], [x1, ym]),
            });
        }
    }
    out
}

impl Engraving {
    /// The grooves' signed distance (negative inside a groove) at `p`.
    pub fn sample(&self, p: &Vector3<f64>) -> Sample {
        self.strokes
            .iter()
            .map(|(a, b)| sdf::capsule(p, a, b, self.groove_radius_mm))
            .reduce(sdf::min)
            .expect("a digit has strokes")
    }

    /// A lower bound of [`Engraving::sample`] at `p`: its distance to the
    /// ball around the text's grooves.
    pub fn lower_bound(&self, p: &Vector3<f64>) -> f64 {
        let centre = self.origin + 0.5 * (self.right * self.size_mm[0] + self.up * self.size_mm[1]);
        let reach = 0.5 * self.size_mm[0].hypot(self.size_mm[1]) + self.groove_radius_mm;
        (p - centre).norm() - reach
    }

    /// `solid` with the grooves cut out, rims rounded. Where the grooves
    /// are farther than the solid's depth plus the rim's blend, the cut
    /// changes nothing and is skipped.
    pub fn cut(&self, solid: Sample, p: &Vector3<f64>) -> Sample {
        if self.lower_bound(p) >= -solid.value + self.rim_blend_mm {
            return solid;
        }
        sdf::smooth_subtract(solid, self.sample(p), self.rim_blend_mm)
    }

    /// Points along every stroke's trace on the face, mm.
    pub fn trace_points(&self) -> Vec<Vector3<f64>> {
        let lift = self.normal * (self.groove_radius_mm - self.depth_mm);
        let mut points = Vec::new();
        for (a, b) in &self.strokes {
            let steps = ((b - a).norm() / STROKE_SAMPLE_MM).ceil().max(1.0) as usize;
            for s in 0..=steps {
                points.push(a + (b - a) * (s as f64 / steps as f64) - lift);
            }
        }
        points
    }

    /// The volume the grooves remove, mm³, estimated from the strokes:
    /// each stroke's length times the groove's cross-section below the
    /// face, plus one round end, less nothing for overlaps at the joints
    /// (an upper estimate by about a cross-section per joint).
    pub fn volume_mm3(&self) -> f64 {
        let r = self.groove_radius_mm;
        let h = r - self.depth_mm;
        // The circular segment of radius r below the chord at height h.
        let theta = 2.0 * (h / r).clamp(-1.0, 1.0).acos();
        let section = 0.5 * r * r * (theta - theta.sin());
        let length: f64 = self.strokes.iter().map(|(a, b)| (b - a).norm()).sum();
        // A round end: half a ball cut by the face, roughly section·r.
        length * section + self.strokes.len() as f64 * section * r * 0.5
    }
}

impl Marker {
    /// Engraves `text` (digits) into the plate's face opposite the bed
    /// (module docs), lengthening the plate when no place on it is free;
    /// `bed` is checked again afterwards.
    pub fn engrave(&mut self, text: &str, bed: &Bed) -> Result<(), GeometryError> {
        if text.is_empty() || text.chars().any(|c| segments(c).is_none()) {
            return Err(GeometryError::BadEngraving(text.to_string()));
        }
        let stroke = stroke_width_mm(self.min_feature_mm, ENGRAVING_DEPTH_MM);
        let depth = ENGRAVING_DEPTH_MM;
        let groove_radius = (0.25 * stroke * stroke + depth * depth) / (2.0 * depth);
        let down = self.down.vector();
        let normal = -down;
        let k = down.iamax();
        let right = Vector3::from_fn(|r, _| if r == (k + 1) % 3 { 1.0 } else { 0.0 });
        let up = normal.cross(&right);
        let size = text_size(text, stroke);
        let strokes_2d = text_strokes(text, stroke);
        let mut grown = false;
        for attempt in 0..2 {
            let face_level =
                self.plate.centre.dot(&normal) + self.plate.half_extents.dot(&normal.abs());
            let make = |origin_r: f64, origin_u: f64| {
                let face_origin = right * origin_r + up * origin_u + normal * face_level;
                let lift = normal * (groove_radius - depth);
                let strokes = strokes_2d
                    .iter()
                    .map(|(a, b)| {
                        (
                            face_origin + right * a[0] + up * a[1] + lift,
                            face_origin + right * b[0] + up * b[1] + lift,
                        )
                    })
                    .collect();
                Engraving {
                    text: text.to_string(),
                    depth_mm: depth,
                    stroke_mm: stroke,
                    groove_radius_mm: groove_radius,
                    rim_blend_mm: RIM_BLEND_STROKES * stroke,
                    normal,
                    face_level_mm: face_level,
                    right,
                    up,
                    origin: face_origin,
                    size_mm: size,
                    plate_grown: grown,
                    strokes,
                }
            };
            let inset = self.plate.rounding + self.min_feature_mm;
            let (cr, cu) = (self.plate.centre.dot(&right), self.plate.centre.dot(&up));
            let (hr, hu) = (
                self.plate.half_extents.dot(&right.abs()),
                self.plate.half_extents.dot(&up.abs()),
            );
            let (r_lo, r_hi) = (cr - hr + inset, cr + hr - inset - size[0]);
            let (u_lo, u_hi) = (cu - hu + inset, cu + hu - inset - size[1]);
            let mut best: Option<((usize, f64), Engraving)> = None;
            if r_hi >= r_lo && u_hi >= u_lo {
                let nr = ((r_hi - r_lo) / PLACEMENT_STEP_MM).floor() as usize;
                let nu = ((u_hi - u_lo) / PLACEMENT_STEP_MM).floor() as usize;
                for i in 0..=nr {
                    for j in 0..=nu {
                        let candidate = make(
                            r_lo + i as f64 * PLACEMENT_STEP_MM,
                            u_lo + j as f64 * PLACEMENT_STEP_MM,
                        );
                        let Some(score) = self.engraving_score(&candidate) else {
                            continue;
                        };
                        let better = best.as_ref().is_none_or(|(b, _)| {
                            score.0 < b.0 || (score.0 == b.0 && score.1 > b.1)
                        });
                        if better {
                            best = Some((score, candidate));
                        }
                    }
                }
            }
            if let Some((_, engraving)) = best {
                self.engraving = Some(engraving);
                self.rebuild_junctions();
                self.check_bed(bed)?;
                return Ok(());
            }
            if attempt == 0 {
                // Lengthen the plate along `up`, away from a screw tab.
                let side = if self
                    .plate
                    .holes
                    .iter()
                    .any(|h| (h.centre - self.plate.centre).dot(&up) > 0.0)
                {
                    -1.0
                } else {
                    1.0
                };
                let blend = self.blend_mm;
                let grow = size[1] + 2.0 * inset + blend + junction_growth(blend);
                self.plate.centre += up * (0.5 * grow * side);
                self.plate.half_extents += up.abs() * (0.5 * grow);
                grown = true;
            }
        }
        Err(GeometryError::BadEngraving(format!(
            "{text} (no room on the base plate clear of the supports)"
        )))
    }

    /// How good a place `engraving` is: (stroke points behind a sphere in
    /// the main view, least clearance to any part, mm), or `None` when a
    /// groove comes within the minimum feature of a part.
    fn engraving_score(&self, engraving: &Engraving) -> Option<(usize, f64)> {
        let half = 0.5 * engraving.stroke_mm + engraving.rim_blend_mm;
        let growth = self.blend_mm + junction_growth(self.blend_mm);
        let mut least = f64::INFINITY;
        let mut hidden = 0usize;
        for q in engraving.trace_points() {
            for strut in &self.struts {
                let gap = sdf::capsule(&q, &strut.a, &strut.b, strut.radius).value - growth - half;
                least = least.min(gap);
            }
            for (i, sphere) in self.spheres.iter().enumerate() {
                let value = match self.teardrops.get(i).copied().flatten() {
                    Some((tip, tip_radius)) => {
                        sdf::round_cone(&q, &sphere.centre, sphere.radius, &tip, tip_radius).value
                    }
                    None => sdf::ball(&q, &sphere.centre, sphere.radius).value,
                };
                least = least.min(value - growth - half);
                let w = q - sphere.centre;
                let along = w.dot(&engraving.normal);
                if along < 0.0 && (w - engraving.normal * along).norm() < sphere.radius {
                    hidden += 1;
                }
            }
            for hole in &self.plate.holes {
                let gap = sdf::cylinder(&q, &hole.centre, &hole.axis, hole.radius).value;
                least = least.min(gap - self.rim_blend_mm - half);
            }
            if least < self.min_feature_mm {
                return None;
            }
        }
        Some((hidden, least))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digits_have_their_segments_and_gaps_of_at_least_the_stroke() {
        let stroke = stroke_width_mm(1.0, ENGRAVING_DEPTH_MM);
        assert_eq!(stroke, 1.2);
        assert_eq!(text_strokes("8", stroke).len(), 7);
        assert_eq!(text_strokes("1", stroke).len(), 2);
        assert_eq!(text_strokes("12", stroke).len(), 7);
        let [w, h] = text_size("8", stroke);
        // Openings inside an 8 are two strokes wide and high.
        assert!((w - 2.0 * stroke) - 2.0 * stroke >= -1e-12);
        assert!(((h - 3.0 * stroke) / 2.0) - 2.0 * stroke >= -1e-12);
        assert!(segments('x').is_none());
    }
}
