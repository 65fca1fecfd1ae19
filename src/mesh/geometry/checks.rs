//! The checks every design must pass: clearances between parts that do
//! not join, open angles where struts leave a sphere, the build volume.

use super::*;

impl Marker {
    /// Whether two struts (by index) share a node.
    fn struts_join(&self, a: usize, b: usize) -> bool {
        let (a, b) = (&self.struts[a], &self.struts[b]);
        a.ends.iter().any(|n| b.ends.contains(n))
    }

    /// Every pair of parts that do not join must keep `min_feature` apart.
    pub(super) fn check_clearances(&self) -> Result<(), GeometryError> {
        let too_close = |first: String, second: String, gap_mm: f64| GeometryError::Clearance {
            first,
            second,
            gap_mm,
            min_feature_mm: self.min_feature_mm,
        };
        // Tolerance for clearances that routing makes exactly equal to the
        // minimum.
        let slack = 1e-9 * (1.0 + self.min_feature_mm);
        for (s, strut) in self.struts.iter().enumerate() {
            for (i, sphere) in self.spheres.iter().enumerate() {
                if strut.ends.contains(&Node::Sphere(i)) {
                    continue;
                }
                let axis = sdf::closest_on_segment(&sphere.centre, &strut.a, &strut.b);
                let gap = (sphere.centre - axis).norm() - sphere.radius - strut.radius;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(
                        self.strut_name(s),
                        format!("sphere {}", sphere.name),
                        gap,
                    ));
                }
            }
            for t in s + 1..self.struts.len() {
                if self.struts_join(s, t) {
                    continue;
                }
                let other = &self.struts[t];
                let gap = segment_distance(&strut.a, &strut.b, &other.a, &other.b)
                    - strut.radius
                    - other.radius;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(self.strut_name(s), self.strut_name(t), gap));
                }
            }
        }
        // Fillets swell a junction beyond its parts by up to
        // `junction_growth`: every blob of a junction (a foot with its
        // thickest strut, or a strut where it leaves its sphere) keeps the
        // minimum feature from parts that do not join it.
        let growth = junction_growth(self.blend_mm);
        for (node, centre, radius, name) in self.junction_blobs() {
            let joins = |s: &Strut| s.ends.contains(&node);
            for (s, strut) in self.struts.iter().enumerate() {
                if joins(strut) {
                    continue;
                }
                let axis = sdf::closest_on_segment(&centre, &strut.a, &strut.b);
                let gap = (centre - axis).norm() - strut.radius - radius - growth;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(name.clone(), self.strut_name(s), gap));
                }
            }
            for (i, sphere) in self.spheres.iter().enumerate() {
                let joined = node == Node::Sphere(i)
                    || self
                        .struts
                        .iter()
                        .any(|s| s.ends.contains(&node) && s.ends.contains(&Node::Sphere(i)));
                if joined {
                    continue;
                }
                let gap = (centre - sphere.centre).norm() - sphere.radius - radius - growth;
                if gap < self.min_feature_mm - slack {
                    return Err(too_close(
                        name.clone(),
                        format!("sphere {}", sphere.name),
                        gap,
                    ));
                }
            }
        }
        Ok(())
    }

    /// The places where fillets swell the solid: each foot (centre, its
    /// thickest strut's radius) and each strut's exit from its sphere.
    fn junction_blobs(&self) -> Vec<(Node, Vector3<f64>, f64, String)> {
        let mut blobs = Vec::new();
        for (k, foot) in self.feet.iter().enumerate() {
            let node = Node::Foot(k);
            blobs.push((
                node,
                foot.position,
                self.node_extent(node),
                format!(
                    "the junction at the foot of {}",
                    self.spheres[foot.sphere].name
                ),
            ));
        }
        for (i, sphere) in self.spheres.iter().enumerate() {
            let node = Node::Sphere(i);
            for strut in self.struts.iter().filter(|s| s.ends.contains(&node)) {
                let far = if strut.ends[0] == node {
                    strut.b
                } else {
                    strut.a
                };
                let exit = sphere.centre + (far - sphere.centre).normalize() * sphere.radius;
                blobs.push((
                    node,
                    exit,
                    strut.radius,
                    format!("the fillet where a strut leaves sphere {}", sphere.name),
                ));
            }
        }
        blobs
    }

    /// The part must fit the build volume, turned on the bed if need be.
    pub(super) fn check_bed(&self, bed: &Bed) -> Result<(), GeometryError> {
        let size_mm = self.print_size_mm();
        let [x, y, z] = bed.0;
        let fits = size_mm[2] <= z
            && ((size_mm[0] <= x && size_mm[1] <= y) || (size_mm[1] <= x && size_mm[0] <= y));
        if fits {
            Ok(())
        } else {
            Err(GeometryError::DoesNotFitBed {
                size_mm,
                bed_mm: bed.0,
            })
        }
    }

    /// Struts that meet at a sphere must part before they leave it:
    /// at the sphere's surface their gap is at least the minimum feature.
    pub(super) fn check_sphere_junctions(&self) -> Result<(), GeometryError> {
        for (i, sphere) in self.spheres.iter().enumerate() {
            let node = Node::Sphere(i);
            let at: Vec<usize> = (0..self.struts.len())
                .filter(|&s| self.struts[s].ends.contains(&node))
                .collect();
            for (k, &s) in at.iter().enumerate() {
                for &t in &at[k + 1..] {
                    let direction = |index: usize| {
                        let strut = &self.struts[index];
                        let far = if strut.ends[0] == node {
                            strut.b
                        } else {
                            strut.a
                        };
                        (far - sphere.centre).normalize()
                    };
                    let angle = direction(s).dot(&direction(t)).clamp(-1.0, 1.0).acos();
                    let gap = 2.0 * sphere.radius * (0.5 * angle).sin()
                        - self.struts[s].radius
                        - self.struts[t].radius;
                    if gap < self.min_feature_mm {
                        return Err(GeometryError::NarrowJunction {
                            sphere: sphere.name.clone(),
                            first: self.strut_name(s),
                            second: self.strut_name(t),
                            angle_deg: angle.to_degrees(),
                            min_feature_mm: self.min_feature_mm,
                        });
                    }
                }
            }
        }
        Ok(())
    }
}
