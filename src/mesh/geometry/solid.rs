//! The designed marker as one solid: [`Marker::design`] and the signed
//! distance of the blended union of its parts.

use super::*;

/// Slack of [`Marker::near`]'s test, mm: far above the rounding of a
/// signed distance, far below any part's size.
const NEAR_SLACK_MM: f64 = 1e-6;

/// The designed marker: every primitive, how they join, and the signed
/// distance of their blended union.
#[derive(Debug, Clone, Serialize)]
pub struct Marker {
    /// The layout's name.
    pub name: String,
    /// One sphere per feature point, in layout order.
    pub spheres: Vec<SphereFeature>,
    /// Post feet on the back plane.
    pub feet: Vec<Foot>,
    /// The foot that serves as hub.
    pub hub: usize,
    /// Every strut.
    pub struts: Vec<Strut>,
    /// The base plate.
    pub plate: Plate,
    /// Screw holes asked for.
    pub mount_holes: Option<MountHoles>,
    /// Fillet (smooth-union) radius at junctions, mm.
    pub blend_mm: f64,
    /// Radius of the rounding of the holes' rims, mm.
    pub rim_blend_mm: f64,
    /// Smallest printable feature, mm.
    pub min_feature_mm: f64,
    /// Main viewing direction.
    pub view: Axis,
    /// Mount axis.
    pub mount: Axis,
    /// How the spheres are held.
    pub structure: Structure,
    /// The axis that points down onto the print bed: the mount axis for
    /// [`Structure::Routed`], the view for [`Structure::Pillars`] (the base
    /// plate lies behind the spheres).
    pub down: Axis,
    /// For [`Structure::Pillars`], the cone under each sphere: (tip,
    /// tip radius), the tip on the sphere's vertical axis below it.
    pub teardrops: Vec<Option<(Vector3<f64>, f64)>>,
    /// For [`Structure::Pillars`], the bed plane: the solid is cut flat at
    /// `p · down = level`.
    pub bed_level: Option<f64>,
    /// Half-angle of the view cone the supports were chosen for, degrees.
    pub view_cone_deg: f64,
    /// The part's number engraved into the plate ([`Marker::engrave`]), if
    /// any.
    pub engraving: Option<Engraving>,
    /// The junctions, each a smooth union of the parts that meet there.
    junctions: Vec<Junction>,
}

/// A junction: the nodes it joins (several when a strut between them is
/// too short for two separate fillets), the balls of its spheres, the
/// pieces of its struts near it, and whether it holds the plate. Its value
/// is the smooth union of those members.
#[derive(Debug, Clone, Serialize)]
struct Junction {
    spheres: Vec<usize>,
    /// Strut pieces (axis start, axis end, radius).
    pieces: Vec<(Vector3<f64>, Vector3<f64>, f64)>,
    plate: bool,
    /// Bounding ball of the members, for culling.
    centre: Vector3<f64>,
    radius: f64,
}

/// Grows an axis-aligned box to bounding-ball form.
fn bounding_ball(boxes: impl Iterator<Item = (Vector3<f64>, f64)>) -> (Vector3<f64>, f64) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for (p, r) in boxes {
        lo = lo.inf(&(p - Vector3::repeat(r)));
        hi = hi.sup(&(p + Vector3::repeat(r)));
    }
    (0.5 * (lo + hi), 0.5 * (hi - lo).norm())
}

impl Marker {
    /// Designs the marker for `layout`: validates the layout and the
    /// options, routes the struts, and checks every clearance.
    pub fn design(layout: &Layout, options: &MarkerOptions) -> Result<Marker, GeometryError> {
        layout.validate()?;
        for (option, value) in [
            ("--strut-diameter", options.strut_diameter_mm),
            ("--min-feature", options.min_feature_mm),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(GeometryError::BadOption { option, value });
            }
        }
        if !(options.view_cone_deg.is_finite() && (0.0..80.0).contains(&options.view_cone_deg)) {
            return Err(GeometryError::BadOption {
                option: "--view-cone (degrees, 0 to below 80)",
                value: options.view_cone_deg,
            });
        }
        let min_feature = options.min_feature_mm;
        if options.strut_diameter_mm < min_feature {
            return Err(GeometryError::StrutTooThin {
                strut_diameter_mm: options.strut_diameter_mm,
                min_feature_mm: min_feature,
            });
        }
        let radius = layout.sphere_radius_mm();
        let strut_radius = 0.5 * options.strut_diameter_mm;
        let max_strut_mm = layout.sphere_diameter_mm - 2.0 * min_feature;
        if options.strut_diameter_mm >= max_strut_mm {
            return Err(GeometryError::StrutTooThick {
                strut_diameter_mm: options.strut_diameter_mm,
                sphere_diameter_mm: layout.sphere_diameter_mm,
                max_mm: max_strut_mm,
            });
        }
        if options.mount == options.view.opposite() {
            return Err(GeometryError::MountTowardsCamera {
                mount: options.mount,
                view: options.view,
            });
        }
        let spheres: Vec<SphereFeature> = layout
            .points
            .iter()
            .map(|p| SphereFeature {
                name: p.name.clone(),
                centre: p.position,
                radius,
            })
            .collect();
        for (i, a) in spheres.iter().enumerate() {
            for b in &spheres[i + 1..] {
                let gap_mm = (a.centre - b.centre).norm() - 2.0 * radius;
                if gap_mm < min_feature {
                    return Err(GeometryError::SpheresTooClose {
                        first: a.name.clone(),
                        second: b.name.clone(),
                        gap_mm,
                        min_feature_mm: min_feature,
                    });
                }
            }
        }

        let mut router = Router {
            spheres: &spheres,
            view: options.view.vector(),
            mount: options.mount.vector(),
            mount_along_view: options.mount == options.view,
            radius,
            strut_radius,
            stub_radius: STUB_DIAMETER_FACTOR * strut_radius,
            clearance: min_feature,
            blend: blend_radius(strut_radius, min_feature),
            views: &options.working_views,
            max_plate_side: options.bed.0[0].min(options.bed.0[1]),
            feet: Vec::new(),
            struts: Vec::new(),
        };
        let (hub, plate, teardrops, bed_level, down) = match options.structure {
            Structure::Routed => {
                router.posts_and_links()?;
                let hub = router.back_plane()?;
                let plate = router.stub_and_plate(hub, options.mount_holes.as_ref());
                (hub, plate, Vec::new(), None, options.mount)
            }
            Structure::Pillars => {
                let tab_side = if options.mount == options.view {
                    let v = options.view.vector();
                    let k = (0..3)
                        .find(|&k| v[k] == 0.0)
                        .expect("an axis is perpendicular");
                    Axis::new(k, false)
                } else {
                    options.mount
                };
                let (plate, teardrops, bed_level) = router.pillars(
                    options.view_cone_deg.to_radians(),
                    tab_side.vector(),
                    options.mount_holes.as_ref(),
                )?;
                (0, plate, teardrops, Some(bed_level), options.view)
            }
        };
        let Router { feet, struts, .. } = router;

        let blend_mm = blend_radius(strut_radius, min_feature);
        let mut marker = Marker {
            name: layout.name.clone(),
            spheres,
            feet,
            hub,
            struts,
            plate,
            mount_holes: options.mount_holes.clone(),
            blend_mm,
            rim_blend_mm: min_feature,
            min_feature_mm: min_feature,
            view: options.view,
            mount: options.mount,
            structure: options.structure,
            down,
            teardrops,
            bed_level,
            view_cone_deg: options.view_cone_deg,
            engraving: None,
            junctions: Vec::new(),
        };
        marker.junctions = marker.build_junctions();
        marker.check_clearances()?;
        marker.check_sphere_junctions()?;
        marker.check_bed(&options.bed)?;
        Ok(marker)
    }

    /// The supports as analytic occluders for the visibility model
    /// ([`crate::visibility`]): every strut a capsule, the cone under each
    /// sphere a round cone, the base plate a box, and the fillet of each
    /// junction that holds a sphere (its smooth union of the spheres' hulls
    /// and strut pieces, as [`Marker::sample`] blends them; a junction's
    /// plate, behind every sphere, is left out). The spheres themselves
    /// are not included.
    pub fn occluders(&self) -> Vec<Occluder> {
        let struts = self.struts.iter().map(|s| Occluder::Capsule {
            a: s.a,
            b: s.b,
            radius: s.radius,
        });
        let cones = self
            .teardrops
            .iter()
            .zip(&self.spheres)
            .filter_map(|(drop, sphere)| {
                drop.map(|(tip, tip_radius)| Occluder::RoundCone {
                    a: sphere.centre,
                    radius_a: sphere.radius,
                    b: tip,
                    radius_b: tip_radius,
                })
            });
        let plate = Occluder::Box {
            centre: self.plate.centre,
            half_extents: self.plate.half_extents,
        };
        let fillets = self
            .junctions
            .iter()
            .filter(|j| !j.spheres.is_empty() && !j.pieces.is_empty())
            .map(|j| Occluder::Fillet {
                hulls: j
                    .spheres
                    .iter()
                    .map(|&i| {
                        let sphere = &self.spheres[i];
                        let (tip, tip_radius) = self
                            .teardrops
                            .get(i)
                            .copied()
                            .flatten()
                            .unwrap_or((sphere.centre, sphere.radius));
                        (sphere.centre, sphere.radius, tip, tip_radius)
                    })
                    .collect(),
                pieces: j.pieces.clone(),
                blend_mm: self.blend_mm,
            });
        struts.chain(cones).chain(fillets).chain([plate]).collect()
    }

    /// A readable name of a strut, e.g. "post P1", "link P3-O0", "back strut
    /// P2-P1" (feet named after their spheres), "stub".
    pub fn strut_name(&self, index: usize) -> String {
        let strut = &self.struts[index];
        let node = |n: Node| match n {
            Node::Sphere(i) => self.spheres[i].name.clone(),
            Node::Foot(k) => self.spheres[self.feet[k].sphere].name.clone(),
            Node::Plate => "plate".to_string(),
        };
        match strut.kind {
            StrutKind::Post => format!("post {}", node(strut.ends[0])),
            StrutKind::Link => format!("link {}-{}", node(strut.ends[0]), node(strut.ends[1])),
            StrutKind::Back => {
                format!("back strut {}-{}", node(strut.ends[0]), node(strut.ends[1]))
            }
            StrutKind::Stub => "mount stub".to_string(),
        }
    }

    /// How far a node's parts reach from its point: the sphere's radius,
    /// the thickest strut at a foot, half the plate's thickness.
    pub(super) fn node_extent(&self, node: Node) -> f64 {
        match node {
            Node::Sphere(i) => self.spheres[i].radius,
            Node::Foot(k) => self
                .struts
                .iter()
                .filter(|s| s.ends.contains(&Node::Foot(k)))
                .map(|s| s.radius)
                .fold(0.0, f64::max),
            Node::Plate => self.plate.half_extents.dot(&self.down.vector().abs()),
        }
    }

    /// How far from a node its fillets can reach: past the node's parts by
    /// twice the blend radius, and past the point where every two of its
    /// struts are a blend radius apart (beyond which the smooth minimum
    /// equals the exact one).
    fn junction_reach(&self, node: Node) -> f64 {
        let at: Vec<&Strut> = self
            .struts
            .iter()
            .filter(|s| s.ends.contains(&node))
            .collect();
        let direction = |s: &Strut| {
            let (near, far) = if s.ends[0] == node {
                (s.a, s.b)
            } else {
                (s.b, s.a)
            };
            (far - near).normalize()
        };
        let mut reach = self.node_extent(node) + 2.0 * self.blend_mm;
        for (k, a) in at.iter().enumerate() {
            for b in &at[k + 1..] {
                let angle = direction(a).dot(&direction(b)).clamp(-1.0, 1.0).acos();
                let half_sine = (0.5 * angle).sin().max(MIN_HALF_ANGLE_SINE);
                reach = reach.max((self.blend_mm + a.radius + b.radius) / (2.0 * half_sine));
            }
        }
        reach
    }

    /// Builds the junctions again (after the plate changed).
    pub(super) fn rebuild_junctions(&mut self) {
        self.junctions = self.build_junctions();
    }

    /// The junctions: nodes joined by a strut whose exposed length (between
    /// the parts of its two nodes) is under two blend radii plus the minimum
    /// feature are merged, so that their fillets form one smooth surface.
    fn build_junctions(&self) -> Vec<Junction> {
        let nodes: Vec<Node> = (0..self.spheres.len())
            .map(Node::Sphere)
            .chain((0..self.feet.len()).map(Node::Foot))
            .chain([Node::Plate])
            .collect();
        let position = |n: Node| nodes.iter().position(|&m| m == n).expect("a node");
        let mut parent: Vec<usize> = (0..nodes.len()).collect();
        fn root(parent: &mut [usize], mut x: usize) -> usize {
            while parent[x] != x {
                parent[x] = parent[parent[x]];
                x = parent[x];
            }
            x
        }
        for strut in &self.struts {
            let exposed = (strut.b - strut.a).norm()
                - self.node_extent(strut.ends[0])
                - self.node_extent(strut.ends[1]);
            if exposed < 2.0 * self.blend_mm + self.min_feature_mm {
                let (a, b) = (position(strut.ends[0]), position(strut.ends[1]));
                let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                parent[ra] = rb;
            }
        }
        if self.structure == Structure::Pillars {
            // Every support foot stands on the plate: one junction.
            let plate = position(Node::Plate);
            for k in 0..self.feet.len() {
                let foot = position(Node::Foot(k));
                let (ra, rb) = (root(&mut parent, foot), root(&mut parent, plate));
                parent[ra] = rb;
            }
        }
        let reach: Vec<f64> = nodes.iter().map(|&n| self.junction_reach(n)).collect();
        let mut junctions = Vec::new();
        for r in 0..nodes.len() {
            if root(&mut parent, r) != r {
                continue;
            }
            let members: Vec<usize> = (0..nodes.len())
                .filter(|&m| root(&mut parent, m) == r)
                .collect();
            let inside = |n: Node| members.contains(&position(n));
            let spheres: Vec<usize> = members
                .iter()
                .filter_map(|&m| match nodes[m] {
                    Node::Sphere(i) => Some(i),
                    _ => None,
                })
                .collect();
            let plate = members.iter().any(|&m| nodes[m] == Node::Plate);
            let mut pieces = Vec::new();
            for strut in &self.struts {
                let (in_a, in_b) = (inside(strut.ends[0]), inside(strut.ends[1]));
                let length = (strut.b - strut.a).norm();
                let unit = (strut.b - strut.a) / length;
                match (in_a, in_b) {
                    (true, true) => pieces.push((strut.a, strut.b, strut.radius)),
                    (true, false) => {
                        let l = reach[position(strut.ends[0])].min(length);
                        pieces.push((strut.a, strut.a + unit * l, strut.radius));
                    }
                    (false, true) => {
                        let l = reach[position(strut.ends[1])].min(length);
                        pieces.push((strut.b - unit * l, strut.b, strut.radius));
                    }
                    (false, false) => {}
                }
            }
            if spheres.is_empty() && pieces.is_empty() && !plate {
                continue;
            }
            let (centre, radius) = bounding_ball(
                spheres
                    .iter()
                    .map(|&i| (self.spheres[i].centre, self.spheres[i].radius))
                    .chain(pieces.iter().flat_map(|&(a, b, r)| [(a, r), (b, r)]))
                    .chain(if plate {
                        vec![
                            (self.plate.centre - self.plate.half_extents, 0.0),
                            (self.plate.centre + self.plate.half_extents, 0.0),
                        ]
                    } else {
                        Vec::new()
                    }),
            );
            junctions.push(Junction {
                spheres,
                pieces,
                plate,
                centre,
                radius,
            });
        }
        junctions
    }

    /// The plate with its holes cut out (rims rounded).
    fn plate_sample(&self, p: &Vector3<f64>) -> Sample {
        let plate = &self.plate;
        let mut value = sdf::rounded_box(p, &plate.centre, &plate.half_extents, plate.rounding);
        for hole in &plate.holes {
            let cut = sdf::cylinder(p, &hole.centre, &hole.axis, hole.radius);
            value = sdf::smooth_subtract(value, cut, self.rim_blend_mm);
        }
        value
    }

    fn junction_sample(&self, junction: &Junction, p: &Vector3<f64>) -> Sample {
        let mut value: Option<Sample> = None;
        let mut blend = |s: Sample| {
            value = Some(match value {
                Some(v) => sdf::smooth_min(v, s, self.blend_mm),
                None => s,
            })
        };
        for &i in &junction.spheres {
            let sphere = &self.spheres[i];
            blend(match self.teardrops.get(i).copied().flatten() {
                Some((tip, tip_radius)) => {
                    sdf::round_cone(p, &sphere.centre, sphere.radius, &tip, tip_radius)
                }
                None => sdf::ball(p, &sphere.centre, sphere.radius),
            });
        }
        if junction.plate {
            blend(self.plate_sample(p));
        }
        for (a, b, radius) in &junction.pieces {
            blend(sdf::capsule(p, a, b, *radius));
        }
        let value = value.expect("every junction has a member");
        if junction.plate {
            // The bed face stays flat: the stub's fillet must not bulge
            // through the plate.
            let m = self.down.vector();
            let bed = self
                .bed_level
                .unwrap_or(self.plate.centre.dot(&m) + self.plate.half_extents.dot(&m.abs()));
            sdf::max(value, sdf::half_space(p, &m, bed))
        } else {
            value
        }
    }

    /// The signed distance of the marker (negative inside) and its gradient
    /// at `p`: the exact minimum of every strut and of every junction's
    /// smooth union. 1-Lipschitz.
    pub fn sample(&self, p: &Vector3<f64>) -> Sample {
        let mut best: Option<Sample> = None;
        for strut in &self.struts {
            // A strut's value is at least its distance to the ball around
            // it, so struts that cannot be the minimum are skipped without
            // changing the result.
            if let Some(b) = &best {
                let half = 0.5 * (strut.b - strut.a).norm();
                let lower = (p - 0.5 * (strut.a + strut.b)).norm() - half - strut.radius;
                if lower > b.value {
                    continue;
                }
            }
            let s = sdf::capsule(p, &strut.a, &strut.b, strut.radius);
            best = Some(best.map_or(s, |b| sdf::min(b, s)));
        }
        for junction in &self.junctions {
            // A junction's value is at least its distance to its bounding
            // ball minus the deepest blend, so junctions that cannot be the
            // minimum are skipped without changing the result.
            if let Some(b) = &best {
                let lower =
                    (p - junction.centre).norm() - junction.radius - self.blend_depth(junction);
                if lower > b.value {
                    continue;
                }
            }
            let s = self.junction_sample(junction, p);
            best = Some(best.map_or(s, |b| sdf::min(b, s)));
        }
        let best = best.expect("a marker has a strut or a junction");
        let best = match self.bed_level {
            Some(level) => sdf::max(best, sdf::half_space(p, &self.down.vector(), level)),
            None => best,
        };
        match &self.engraving {
            Some(engraving) => engraving.cut(best, p),
            None => best,
        }
    }

    /// The marker cut down to the struts and junctions that can be its
    /// nearest part somewhere within `radius` of `centre`: there its
    /// [`Marker::sample`] is exactly this marker's, at a fraction of the
    /// cost. A part whose value at `centre`, less `radius`, exceeds the
    /// smallest value at `centre` plus `radius` is larger than another
    /// part everywhere in the ball (every part is 1-Lipschitz), so it is
    /// never the minimum there and leaving it out changes nothing.
    pub fn near(&self, centre: &Vector3<f64>, radius: f64) -> Marker {
        let struts: Vec<f64> = self
            .struts
            .iter()
            .map(|s| sdf::capsule(centre, &s.a, &s.b, s.radius).value)
            .collect();
        let junctions: Vec<f64> = self
            .junctions
            .iter()
            .map(|j| self.junction_sample(j, centre).value)
            .collect();
        let upper = struts
            .iter()
            .chain(&junctions)
            .fold(f64::INFINITY, |a, &b| a.min(b))
            + radius;
        // Rounding in the values at the centre must not drop a part that
        // can be the minimum.
        let keep = |value: &f64| value - radius <= upper + NEAR_SLACK_MM;
        let mut near = self.clone();
        near.struts = self
            .struts
            .iter()
            .zip(&struts)
            .filter(|(_, v)| keep(v))
            .map(|(s, _)| s.clone())
            .collect();
        near.junctions = self
            .junctions
            .iter()
            .zip(&junctions)
            .filter(|(_, v)| keep(v))
            .map(|(j, _)| j.clone())
            .collect();
        near
    }

    /// The signed distance alone.
    pub fn signed_distance(&self, p: &Vector3<f64>) -> f64 {
        self.sample(p).value
    }

    /// Axis-aligned bounds of the solid (min, max), mm: the primitives'
    /// bounds grown by the most that blending can add.
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        let mut grow = |p: Vector3<f64>, r: f64| {
            lo = lo.inf(&(p - Vector3::repeat(r)));
            hi = hi.sup(&(p + Vector3::repeat(r)));
        };
        for s in &self.spheres {
            grow(s.centre, s.radius);
        }
        for s in &self.struts {
            grow(s.a, s.radius);
            grow(s.b, s.radius);
        }
        grow(self.plate.centre - self.plate.half_extents, 0.0);
        grow(self.plate.centre + self.plate.half_extents, 0.0);
        let depth = self
            .junctions
            .iter()
            .map(|j| self.blend_depth(j))
            .fold(0.0, f64::max);
        let margin = Vector3::repeat(depth);
        let (mut lo, mut hi) = (lo - margin, hi + margin);
        if let Some(level) = self.bed_level {
            // The solid ends at the bed plane: p · down ≤ level.
            let down = self.down.vector();
            let k = down.iamax();
            if down[k] > 0.0 {
                hi[k] = hi[k].min(level);
            } else {
                lo[k] = lo[k].max(-level);
            }
        }
        (lo, hi)
    }

    /// The most a junction's smooth union can lie below its members'
    /// minimum: a quarter blend radius per smooth minimum taken.
    fn blend_depth(&self, junction: &Junction) -> f64 {
        let members = junction.spheres.len() + junction.pieces.len() + usize::from(junction.plate);
        0.25 * self.blend_mm * members.saturating_sub(1) as f64
    }

    /// For each axis, the coordinates of the planes perpendicular to it
    /// that a strut lies tangent to along a line (struts perpendicular to
    /// the axis), each with a flag: `true` for a strut oblique to the other
    /// axes, whose tangent strip runs diagonally across the grid.
    pub fn tangent_planes(&self) -> [Vec<(f64, bool)>; 3] {
        let mut planes: [Vec<(f64, bool)>; 3] = Default::default();
        if let Some(level) = self.bed_level {
            let down = self.down.vector();
            let k = down.iamax();
            planes[k].push((level * down[k], false));
        }
        for strut in &self.struts {
            let d = strut.b - strut.a;
            let length = d.norm();
            if length == 0.0 {
                continue;
            }
            let along_axis = (0..3).any(|k| (d[k].abs() - length).abs() <= 1e-12 * length);
            for (k, axis_planes) in planes.iter_mut().enumerate() {
                if d[k].abs() <= 1e-12 * length {
                    axis_planes.push((strut.a[k] - strut.radius, !along_axis));
                    axis_planes.push((strut.a[k] + strut.radius, !along_axis));
                }
            }
        }
        planes
    }

    /// The thinnest feature the mesh must resolve, mm: the strut radius,
    /// the fillet radius, the holes' radius and rim rounding, and the
    /// smallest gap (the minimum feature size).
    pub fn finest_feature_mm(&self) -> f64 {
        let mut finest = self
            .struts
            .iter()
            .map(|s| s.radius)
            .fold(self.min_feature_mm, f64::min)
            .min(self.blend_mm)
            .min(self.plate.rounding);
        for hole in &self.plate.holes {
            finest = finest.min(hole.radius).min(self.rim_blend_mm);
        }
        if let Some(engraving) = &self.engraving {
            finest = finest
                .min(engraving.depth_mm)
                .min(0.5 * engraving.stroke_mm);
        }
        finest
    }
}
