//! Where the supports run: posts, links and back struts for the routed
//! structure, pillars from a base plate for the printable one.

use super::*;

/// Builds the struts (see the module documentation).
pub(super) struct Router<'a> {
    pub(super) spheres: &'a [SphereFeature],
    pub(super) view: Vector3<f64>,
    pub(super) mount: Vector3<f64>,
    pub(super) mount_along_view: bool,
    pub(super) radius: f64,
    pub(super) strut_radius: f64,
    pub(super) stub_radius: f64,
    pub(super) clearance: f64,
    pub(super) blend: f64,
    /// Camera centres of the working range's views (empty: the view cone).
    pub(super) views: &'a [Vector3<f64>],
    /// The widest base plate the bed takes (its shorter side), mm.
    pub(super) max_plate_side: f64,
    pub(super) feet: Vec<Foot>,
    pub(super) struts: Vec<Strut>,
}

impl Router<'_> {
    /// Step 1: a post back along the view from every sphere, unless it
    /// would pass within the clearance (plus the swell of the fillet where
    /// it leaves its sphere) of a sphere behind; then a link to the first
    /// sphere behind whose disc overlaps this one's in the main view (or,
    /// failing those, the nearest sphere behind) to which a straight link
    /// keeps clear of every other sphere and meets that sphere's struts at
    /// an open angle.
    pub(super) fn posts_and_links(&mut self) -> Result<(), GeometryError> {
        let depth = |i: usize| self.spheres[i].centre.dot(&self.view);
        // Behind the rearmost sphere, far enough that the fillets where its
        // post leaves it and where the post meets the back plane stay apart.
        let back_depth = (0..self.spheres.len())
            .map(depth)
            .fold(f64::NEG_INFINITY, f64::max)
            + self.radius
            + 2.0 * self.blend
            + self.clearance
            + self.stub_radius;
        let growth = junction_growth(self.blend);
        let reach = self.radius + self.strut_radius + growth + self.clearance;
        let overlap = reach.max(2.0 * self.radius);
        // Decide from the back to the front, so that when a sphere picks a
        // sphere behind it, that sphere's own strut and the links already
        // arriving at it are known (to keep the junction open).
        let mut order: Vec<usize> = (0..self.spheres.len()).collect();
        order.sort_by(|&a, &b| depth(b).total_cmp(&depth(a)));
        let mut link_to: Vec<Option<usize>> = vec![None; self.spheres.len()];
        let mut posts = Vec::new();
        for i in order {
            let sphere = &self.spheres[i];
            // (index, distance behind, distance across the view)
            let behind: Vec<(usize, f64, f64)> = self
                .spheres
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(j, other)| {
                    let offset = other.centre - sphere.centre;
                    let along = offset.dot(&self.view);
                    (j, along, (offset - self.view * along).norm())
                })
                .filter(|&(_, along, _)| along > 0.0)
                .collect();
            if behind.iter().all(|&(_, _, across)| across >= reach) {
                posts.push(i);
                continue;
            }
            // First the spheres whose disc overlaps this one's in the main
            // view, nearest first (a link to them hides best); failing
            // those, any sphere behind, by distance.
            let mut candidates: Vec<(usize, f64)> = behind
                .iter()
                .filter(|&&(_, _, across)| across < overlap)
                .map(|&(j, along, _)| (j, along))
                .collect();
            candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
            let mut others: Vec<(usize, f64)> = behind
                .iter()
                .filter(|&&(_, _, across)| across >= overlap)
                .map(|&(j, along, across)| (j, along.hypot(across)))
                .collect();
            others.sort_by(|a, b| a.1.total_cmp(&b.1));
            candidates.extend(others);
            let clear = |j: usize| {
                let (a, b) = (sphere.centre, self.spheres[j].centre);
                self.spheres.iter().enumerate().all(|(k, other)| {
                    k == i || k == j || {
                        let axis = sdf::closest_on_segment(&other.centre, &a, &b);
                        (other.centre - axis).norm() - other.radius - self.strut_radius
                            >= self.clearance + growth
                    }
                })
            };
            // The struts already at j: its own (a post along the view or a
            // link further back) and the links arriving from the front.
            let open_at = |j: usize| {
                let centre = self.spheres[j].centre;
                let arriving = (sphere.centre - centre).normalize();
                let own = match link_to[j] {
                    Some(k) => (self.spheres[k].centre - centre).normalize(),
                    None => self.view,
                };
                std::iter::once(own)
                    .chain(
                        (0..self.spheres.len())
                            .filter(|&k| link_to[k] == Some(j))
                            .map(|k| (self.spheres[k].centre - centre).normalize()),
                    )
                    .all(|u| {
                        let angle = arriving.dot(&u).clamp(-1.0, 1.0).acos();
                        2.0 * self.radius * (0.5 * angle).sin() - 2.0 * self.strut_radius
                            >= self.clearance
                    })
            };
            let j = candidates
                .iter()
                .map(|&(j, _)| j)
                .find(|&j| clear(j) && open_at(j))
                .ok_or_else(|| GeometryError::RoutingFailed {
                    from: format!("sphere {}", sphere.name),
                    reason: "its post would pass too close to a sphere behind it, and no straight link to a sphere behind it keeps clear of the others and meets that sphere's struts at an open angle".into(),
                })?;
            link_to[i] = Some(j);
        }
        for (i, target) in link_to.iter().enumerate() {
            if let Some(j) = *target {
                self.struts.push(Strut {
                    kind: StrutKind::Link,
                    ends: [Node::Sphere(i), Node::Sphere(j)],
                    a: self.spheres[i].centre,
                    b: self.spheres[j].centre,
                    radius: self.strut_radius,
                });
            }
        }
        posts.sort_unstable();
        for i in posts {
            let centre = self.spheres[i].centre;
            let foot = centre + self.view * (back_depth - depth(i));
            self.feet.push(Foot {
                position: foot,
                sphere: i,
            });
            self.struts.push(Strut {
                kind: StrutKind::Post,
                ends: [Node::Sphere(i), Node::Foot(self.feet.len() - 1)],
                a: centre,
                b: foot,
                radius: self.strut_radius,
            });
        }
        Ok(())
    }

    /// The foot at which the stub starts: the one furthest along the mount
    /// axis (ties: nearest the hub), or the hub when mounting along the
    /// view.
    fn mount_foot(&self, hub: usize) -> usize {
        if self.mount_along_view {
            return hub;
        }
        let along = |k: usize| self.feet[k].position.dot(&self.mount);
        let best = (0..self.feet.len())
            .map(along)
            .fold(f64::NEG_INFINITY, f64::max);
        (0..self.feet.len())
            .filter(|&k| along(k) >= best - 1e-9)
            .min_by(|&a, &b| {
                let d = |k: usize| (self.feet[k].position - self.feet[hub].position).norm();
                d(a).total_cmp(&d(b))
            })
            .expect("there is at least one foot")
    }

    /// Clearance radius of a foot: the stub's where the stub starts.
    fn foot_radius(&self, k: usize, mount_foot: usize) -> f64 {
        if k == mount_foot && !self.mount_along_view {
            self.stub_radius
        } else {
            self.strut_radius
        }
    }

    /// Step 2: back struts from every foot to the hub, as a shortest-path
    /// tree whose struts keep clear of the other feet and of each other and
    /// meet at open angles. Returns the hub.
    pub(super) fn back_plane(&mut self) -> Result<usize, GeometryError> {
        let count = self.feet.len();
        let centroid = self.feet.iter().map(|f| f.position).sum::<Vector3<f64>>() / count as f64;
        let hub = (0..count)
            .min_by(|&a, &b| {
                let d = |k: usize| (self.feet[k].position - centroid).norm();
                d(a).total_cmp(&d(b))
            })
            .expect("there is at least one foot");
        let mount_foot = self.mount_foot(hub);
        let position = |k: usize| self.feet[k].position;
        let min_cos = MIN_JUNCTION_ANGLE_DEG.to_radians().cos();

        // Path length to the hub along the tree, and the back struts so far.
        let mut path: Vec<Option<f64>> = vec![None; count];
        path[hub] = Some(0.0);
        let mut edges: Vec<(usize, usize)> = Vec::new();
        // Grow the tree one foot at a time: of all feet not yet joined, the
        // one with the shortest feasible path to the hub.
        let feasible = |foot: usize, target: usize, edges: &[(usize, usize)]| -> bool {
            let (a, b) = (position(foot), position(target));
            // Clear of every other foot.
            let feet_clear = (0..count).filter(|&g| g != foot && g != target).all(|g| {
                let axis = sdf::closest_on_segment(&position(g), &a, &b);
                (position(g) - axis).norm()
                    >= self.strut_radius
                        + self.foot_radius(g, mount_foot)
                        + junction_growth(self.blend)
                        + self.clearance
            });
            // Clear of the back struts it does not join.
            let struts_clear = edges
                .iter()
                .filter(|&&(p, q)| p != foot && q != foot && p != target && q != target)
                .all(|&(p, q)| {
                    segment_distance(&a, &b, &position(p), &position(q))
                        >= 2.0 * self.strut_radius + self.clearance
                });
            // Open angles with the struts already at the target: at
            // least MIN_JUNCTION_ANGLE_DEG, and wide enough that the two
            // struts are a blend radius plus the clearance apart before
            // the shorter one ends (else the fillet between them would
            // leave a slit).
            let direction = (a - b).normalize();
            let angles_open = edges
                .iter()
                .filter_map(|&(p, q)| {
                    if p == target {
                        Some(q)
                    } else if q == target {
                        Some(p)
                    } else {
                        None
                    }
                })
                .all(|other| {
                    let shorter = (a - b).norm().min((position(other) - b).norm());
                    let apart = 2.0 * self.strut_radius + self.blend + self.clearance;
                    let needed = 2.0 * (apart / (2.0 * shorter)).min(1.0).asin();
                    let cos = direction.dot(&(position(other) - b).normalize());
                    cos <= min_cos && cos <= needed.cos()
                });
            feet_clear && struts_clear && angles_open
        };
        while path.iter().any(Option::is_none) {
            let joined = &path;
            let best = (0..count)
                .filter(|&foot| joined[foot].is_none())
                .flat_map(|foot| {
                    (0..count).filter_map(move |t| {
                        joined[t].map(|p| (p + (position(foot) - position(t)).norm(), foot, t))
                    })
                })
                .filter(|&(_, foot, target)| feasible(foot, target, &edges))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((length, foot, target)) = best else {
                let foot = (0..count)
                    .find(|&k| path[k].is_none())
                    .expect("a foot is left");
                return Err(GeometryError::RoutingFailed {
                    from: format!("foot of {}", self.spheres[self.feet[foot].sphere].name),
                    reason: "no back strut towards the hub keeps clear of the other feet and struts with open junction angles".into(),
                });
            };
            path[foot] = Some(length);
            edges.push((foot, target));
        }
        for (foot, target) in edges {
            self.struts.push(Strut {
                kind: StrutKind::Back,
                ends: [Node::Foot(foot), Node::Foot(target)],
                a: position(foot),
                b: position(target),
                radius: self.strut_radius,
            });
        }
        Ok(hub)
    }

    /// [`Structure::Pillars`]: a cone under every sphere, a support from its
    /// tip down to the base plate (or onto a sphere behind), and the plate
    /// behind every sphere, perpendicular to the view, on the bed. Supports
    /// are chosen back to front: straight down when that keeps clear of
    /// the other parts and covers no sphere from the view cone (of
    /// half-angle `cone_rad`), else the slant and direction (or the sphere
    /// to stand on) that covers least. Returns the plate, the cones and
    /// the bed level (along the view).
    #[allow(clippy::type_complexity)]
    pub(super) fn pillars(
        &mut self,
        cone_rad: f64,
        tab_side: Vector3<f64>,
        holes: Option<&MountHoles>,
    ) -> Result<(Plate, Vec<Option<(Vector3<f64>, f64)>>, f64), GeometryError> {
        let v = self.view;
        let count = self.spheres.len();
        let (radius, strut_radius) = (self.radius, self.strut_radius);
        let drop_length = (radius - strut_radius) / TEARDROP_HALF_ANGLE_DEG.to_radians().sin();
        let tips: Vec<Vector3<f64>> = self
            .spheres
            .iter()
            .map(|s| s.centre + v * drop_length)
            .collect();
        let depth = |p: &Vector3<f64>| p.dot(&v);
        let inner = tips.iter().map(depth).fold(f64::NEG_INFINITY, f64::max)
            + strut_radius
            + 2.0 * self.blend
            + self.clearance;
        let growth = junction_growth(self.blend);
        let directions = view_cone_directions(&v, cone_rad, 2, 12);
        let kv = v.iamax();
        let unit = |k: usize| Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
        let (e1, e2) = (unit((kv + 1) % 3), unit((kv + 2) % 3));
        let mut order: Vec<usize> = (0..count).collect();
        order.sort_by(|&a, &b| {
            depth(&self.spheres[b].centre).total_cmp(&depth(&self.spheres[a].centre))
        });
        // Each sphere's support: its end and the sphere it stands on, if any.
        let mut supports: Vec<Option<(Vector3<f64>, Option<usize>)>> = vec![None; count];
        let hits = |q: &Vector3<f64>, d: &Vector3<f64>, centre: &Vector3<f64>, r: f64| {
            let w = centre - q;
            let t = w.dot(d);
            if t < 0.0 {
                w.norm_squared() < r * r
            } else {
                w.norm_squared() - t * t < r * r
            }
        };
        let centroid = self.spheres.iter().map(|s| s.centre).sum::<Vector3<f64>>() / count as f64;
        for &i in &order {
            let tip = tips[i];
            // Slanted supports try directions towards the middle of the
            // layout first, which keeps the plate small.
            let inward = centroid - self.spheres[i].centre;
            let phi_inward = inward.dot(&e2).atan2(inward.dot(&e1));
            let mut candidates: Vec<(Vector3<f64>, Option<usize>)> = Vec::new();
            for &slant_deg in SUPPORT_SLANTS_DEG {
                let slant = slant_deg.to_radians();
                let azimuths = if slant_deg == 0.0 {
                    1
                } else {
                    SUPPORT_AZIMUTHS
                };
                for a in 0..azimuths {
                    // 0, +1, −1, +2, −2, … steps away from inward.
                    let step = a.div_ceil(2) as f64 * if a % 2 == 1 { 1.0 } else { -1.0 };
                    let phi = phi_inward + std::f64::consts::TAU * step / azimuths as f64;
                    let direction =
                        v * slant.cos() + (e1 * phi.cos() + e2 * phi.sin()) * slant.sin();
                    candidates.push((
                        tip + direction * ((inner - depth(&tip)) / slant.cos()),
                        None,
                    ));
                }
            }
            let steepest = SUPPORT_SLANTS_DEG
                .iter()
                .fold(0.0f64, |m, &s| m.max(s))
                .to_radians();
            for j in 0..count {
                if j == i
                    || supports[j].is_none()
                    || supports
                        .iter()
                        .any(|s| matches!(s, Some((_, Some(k))) if *k == j))
                {
                    continue;
                }
                let offset = self.spheres[j].centre - tip;
                let along = offset.dot(&v);
                let across = (offset - v * along).norm();
                if along > radius + strut_radius + 2.0 * self.blend
                    && across <= along * steepest.tan()
                {
                    candidates.push((self.spheres[j].centre, Some(j)));
                }
            }
            // Feet within the layout's footprint (grown by a sphere
            // diameter) first, which keeps the plate small; any foot only
            // when none of those is feasible.
            let footprint = |p: &Vector3<f64>| {
                [e1, e2].iter().all(|e| {
                    let (lo, hi) = self
                        .spheres
                        .iter()
                        .map(|s| s.centre.dot(e))
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                            (lo.min(x), hi.max(x))
                        });
                    (lo - 2.0 * radius..=hi + 2.0 * radius).contains(&p.dot(e))
                })
            };
            let (inside, outside): (Vec<_>, Vec<_>) =
                candidates.into_iter().partition(|(end, _)| footprint(end));
            let mut best: Option<(f64, Vector3<f64>, Option<usize>)> = None;
            for (end, onto) in inside.into_iter().chain(outside) {
                // (For a working range, feet outside the footprint are
                // tried too while every foot inside hides some view.)
                let settled = best
                    .as_ref()
                    .is_some_and(|b| self.views.is_empty() || b.0 == 0.0);
                if settled && !footprint(&end) {
                    break;
                }
                // A foot outside the footprint must leave a plate that
                // fits the bed.
                let plate_margin = strut_radius + self.blend + self.clearance + PLATE_ROUNDING_MM;
                let fits_bed = [e1, e2].iter().all(|e| {
                    let (lo, hi) = self
                        .spheres
                        .iter()
                        .map(|s| {
                            (
                                s.centre.dot(e) - 2.0 * radius,
                                s.centre.dot(e) + 2.0 * radius,
                            )
                        })
                        .chain(supports.iter().flatten().map(|(p, _)| (p.dot(e), p.dot(e))))
                        .chain([(end.dot(e), end.dot(e))])
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, b)| {
                            (lo.min(a), hi.max(b))
                        });
                    hi - lo + 2.0 * plate_margin <= self.max_plate_side
                });
                if !footprint(&end) && !fits_bed {
                    continue;
                }
                // Clear of every other sphere and its cone, and of every
                // support chosen so far (but the one it stands on).
                let clear_spheres = (0..count).filter(|&k| k != i && Some(k) != onto).all(|k| {
                    segment_distance(&tip, &end, &self.spheres[k].centre, &tips[k])
                        - radius
                        - strut_radius
                        >= self.clearance + growth
                });
                let clear_supports =
                    (0..count)
                        .filter(|&k| k != i && Some(k) != onto)
                        .all(|k| match supports[k] {
                            Some((other_end, _)) => {
                                segment_distance(&tip, &end, &tips[k], &other_end)
                                    - 2.0 * strut_radius
                                    >= self.clearance + growth
                            }
                            None => true,
                        });
                if !(clear_spheres && clear_supports) {
                    continue;
                }
                let length = (end - tip).norm();
                let steps = (length / SUPPORT_SAMPLE_MM).ceil().max(1.0) as usize;
                if !self.views.is_empty() {
                    // How many (view, sphere) pairs of the working range it
                    // hides any of.
                    let limit = best.as_ref().map_or(usize::MAX, |b| b.0 as usize);
                    let score = self.views_covered(i, &tip, &end, steps, limit);
                    if best.as_ref().is_none_or(|b| (score as f64) < b.0) {
                        best = Some((score as f64, end, onto));
                    }
                    if score == 0 {
                        break;
                    }
                    continue;
                }
                // How much it covers: sample points along it, rays towards
                // every other sphere in the cone that its own sphere does
                // not shadow.
                let mut covered = 0usize;
                for step in 0..=steps {
                    let q = tip + (end - tip) * (step as f64 / steps as f64);
                    for d in &directions {
                        if hits(&q, &(-d), &self.spheres[i].centre, radius - strut_radius) {
                            continue;
                        }
                        covered += (0..count)
                            .filter(|&k| {
                                k != i
                                    && hits(&q, d, &self.spheres[k].centre, radius + strut_radius)
                            })
                            .count();
                    }
                }
                let score = covered as f64 * length / steps as f64;
                if best.as_ref().is_none_or(|b| score < b.0) {
                    best = Some((score, end, onto));
                }
                if score == 0.0 {
                    break;
                }
            }
            let Some((_, end, onto)) = best else {
                return Err(GeometryError::RoutingFailed {
                    from: format!("sphere {}", self.spheres[i].name),
                    reason: "no support down to the base plate or onto a sphere behind it, at most 35 degrees from the view, keeps clear of the other spheres and supports (--structure routed may route it)".into(),
                });
            };
            supports[i] = Some((end, onto));
        }
        // The struts, and feet on the plate.
        for i in 0..count {
            let (end, onto) = supports[i].expect("every sphere has a support");
            match onto {
                Some(j) => self.struts.push(Strut {
                    kind: StrutKind::Link,
                    ends: [Node::Sphere(i), Node::Sphere(j)],
                    a: tips[i],
                    b: end,
                    radius: strut_radius,
                }),
                None => {
                    self.feet.push(Foot {
                        position: end,
                        sphere: i,
                    });
                    self.struts.push(Strut {
                        kind: StrutKind::Post,
                        ends: [Node::Sphere(i), Node::Foot(self.feet.len() - 1)],
                        a: tips[i],
                        b: end,
                        radius: strut_radius,
                    });
                }
            }
        }
        // The plate: the feet's footprint with a margin for the fillets, at
        // least PLATE_MIN_SIDE_MM, and a tab for the screw holes on the
        // mount side (two holes) or on both sides (four).
        let margin = strut_radius + self.blend + self.clearance + PLATE_ROUNDING_MM;
        let thickness = PLATE_THICKNESS_MM;
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for foot in &self.feet {
            for (k, e) in [e1, e2].iter().enumerate() {
                lo[k] = lo[k].min(foot.position.dot(e) - margin);
                hi[k] = hi[k].max(foot.position.dot(e) + margin);
            }
        }
        for k in 0..2 {
            let grow = (PLATE_MIN_SIDE_MM - (hi[k] - lo[k])).max(0.0);
            lo[k] -= 0.5 * grow;
            hi[k] += 0.5 * grow;
        }
        let mut hole_centres: Vec<[f64; 2]> = Vec::new();
        let hole_radius = 0.5 * holes.map_or(0.0, |h| h.diameter_mm);
        if let Some(spec) = holes {
            let wall = hole_radius.max(2.0 * self.clearance);
            let tab = 2.0 * (hole_radius + wall);
            // The tab axis (0 or 1) and side; the holes spread across it.
            let axis = if tab_side.dot(&e1) != 0.0 { 0 } else { 1 };
            let positive = tab_side.dot(if axis == 0 { &e1 } else { &e2 }) > 0.0;
            let other = 1 - axis;
            let spread = 0.25 * (hi[other] - lo[other]);
            let mid = 0.5 * (hi[other] + lo[other]);
            let mut sides = vec![positive];
            if spec.count == 4 {
                sides.push(!positive);
            }
            for side in sides {
                let at = if side {
                    hi[axis] += tab;
                    hi[axis] - 0.5 * tab
                } else {
                    lo[axis] -= tab;
                    lo[axis] + 0.5 * tab
                };
                for across in [mid - spread, mid + spread] {
                    let mut c = [0.0; 2];
                    c[axis] = at;
                    c[other] = across;
                    hole_centres.push(c);
                }
            }
        }
        let bed_level = inner + thickness;
        // The bed face's rounded rim rises no more than one layer before it
        // is steep enough to print (PILLAR_PLATE_ROUNDING_MM).
        let depth_mid = inner + 0.5 * thickness;
        let point = |a: f64, b: f64, d: f64| e1 * a + e2 * b + v * d;
        let centre = point(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), depth_mid);
        let half_extents = (point(
            0.5 * (hi[0] - lo[0]),
            0.5 * (hi[1] - lo[1]),
            0.5 * thickness,
        ))
        .abs();
        let plate = Plate {
            centre,
            half_extents,
            rounding: PILLAR_PLATE_ROUNDING_MM,
            holes: hole_centres
                .iter()
                .map(|c| Hole {
                    centre: point(c[0], c[1], inner + 0.5 * thickness),
                    axis: v,
                    radius: hole_radius,
                })
                .collect(),
        };
        let teardrops = tips.iter().map(|&tip| Some((tip, strut_radius))).collect();
        Ok((plate, teardrops, bed_level))
    }

    /// The (view, sphere) pairs of the working range in which the support
    /// of sphere `from` along `tip`–`end` hides part of another sphere
    /// (balls of the strut's radius every [`SUPPORT_SAMPLE_MM`] along it,
    /// tested against each sphere's cone of sight lines); counting stops
    /// past `limit`.
    fn views_covered(
        &self,
        from: usize,
        tip: &Vector3<f64>,
        end: &Vector3<f64>,
        steps: usize,
        limit: usize,
    ) -> usize {
        let points: Vec<Vector3<f64>> = (0..=steps)
            .map(|step| tip + (end - tip) * (step as f64 / steps as f64))
            .collect();
        let mut covered = 0usize;
        for camera in self.views {
            for (k, sphere) in self.spheres.iter().enumerate() {
                if k == from {
                    continue;
                }
                let hides = points.iter().any(|q| {
                    (q - sphere.centre).norm() + self.strut_radius > sphere.radius
                        && ball_covers_sphere(
                            camera,
                            q,
                            self.strut_radius,
                            &sphere.centre,
                            sphere.radius,
                        )
                });
                covered += usize::from(hides);
                if covered > limit {
                    return covered;
                }
            }
        }
        covered
    }

    /// Step 3: the stub and the base plate with its holes.
    pub(super) fn stub_and_plate(&mut self, hub: usize, holes: Option<&MountHoles>) -> Plate {
        let mount_foot = self.mount_foot(hub);
        let start = self.feet[mount_foot].position;
        let m = self.mount;
        // The plate's inner face: beyond every other part by the clearance,
        // and far enough out that the stub between the foot's fillets and
        // the plate's stays exposed for two blend radii plus the clearance
        // (so the two junctions, and their fillets, stay apart).
        let shortest = start.dot(&m) + self.stub_radius + 2.0 * self.blend + self.clearance;
        let inner = if self.mount_along_view {
            (start.dot(&m) + STUB_LENGTH_MM).max(shortest)
        } else {
            let spheres = self
                .spheres
                .iter()
                .map(|s| s.centre.dot(&m) + s.radius)
                .fold(f64::NEG_INFINITY, f64::max);
            let struts = self
                .struts
                .iter()
                .flat_map(|s| [s.a.dot(&m) + s.radius, s.b.dot(&m) + s.radius])
                .fold(f64::NEG_INFINITY, f64::max);
            (spheres.max(struts) + self.clearance).max(shortest)
        };
        let thickness = PLATE_THICKNESS_MM.max(self.stub_radius + 2.0 * self.clearance);
        let face_point = start + m * (inner - start.dot(&m));
        let centre = face_point + m * (0.5 * thickness);
        // The stub ends on the plate's inner face; its round end sinks into
        // the plate (thicker than the stub's radius) and leaves the bed face
        // flat.
        self.struts.push(Strut {
            kind: StrutKind::Stub,
            ends: [Node::Foot(mount_foot), Node::Plate],
            a: start,
            b: face_point,
            radius: self.stub_radius,
        });

        // In-plane axes: `across` is perpendicular to both the mount axis and
        // the view (or the first object axis perpendicular to the mount).
        let across = if self.mount_along_view {
            let k = (0..3)
                .find(|&k| m[k] == 0.0)
                .expect("an axis is perpendicular");
            Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 })
        } else {
            m.cross(&self.view)
        };
        let other = m.cross(&across);
        let blend = self.blend;
        let (offset, side) = match holes {
            Some(spec) => {
                let hole_radius = 0.5 * spec.diameter_mm;
                // Clear of the stub and its fillet, with a wall to the edge.
                let offset = self.stub_radius + blend + self.clearance + hole_radius;
                let wall = hole_radius.max(2.0 * self.clearance);
                (offset, 2.0 * (offset + hole_radius + wall))
            }
            None => (0.0, 0.0),
        };
        let side = side.max(PLATE_MIN_SIDE_MM).max(4.0 * self.stub_radius);
        let half_extents = Vector3::from_fn(|k, _| {
            if m[k] != 0.0 {
                0.5 * thickness
            } else {
                0.5 * side
            }
        });
        let hole_offsets: Vec<Vector3<f64>> = match holes.map(|h| h.count) {
            Some(4) => [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]
                .iter()
                .map(|&(a, b)| (across * a + other * b) * (offset / 2f64.sqrt()))
                .collect(),
            Some(_) => vec![across * offset, -across * offset],
            None => Vec::new(),
        };
        Plate {
            centre,
            half_extents,
            rounding: PLATE_ROUNDING_MM,
            holes: hole_offsets
                .into_iter()
                .map(|o| Hole {
                    centre: centre + o,
                    axis: m,
                    radius: 0.5 * holes.map_or(0.0, |h| h.diameter_mm),
                })
                .collect(),
        }
    }
}

/// The part `export` would build for `layout` with `options`, its supports
/// routed to clear the views of `range` (no mesh is made).
pub fn marker_for_range(
    layout: &crate::layout::Layout,
    options: &MarkerOptions,
    range: &crate::visibility::WorkingRange,
) -> Result<Marker, GeometryError> {
    Marker::design(layout, &routed_for(options.clone(), layout, range))
}

/// `options` with the supports routed to clear the views of `range`.
fn routed_for(
    options: MarkerOptions,
    layout: &crate::layout::Layout,
    range: &crate::visibility::WorkingRange,
) -> MarkerOptions {
    MarkerOptions {
        working_views: range.clear_views(&layout.positions(), layout.sphere_diameter_mm),
        ..options
    }
}

/// `options` with the supports routed as `export` routes them for `layout`
/// when no range is given: for the search's range recorded in the
/// layout's provenance (the paper camera, the default `--max-hidden`), or,
/// when it records none, for the view cone (`options` unchanged).
pub fn routed_as_recorded(
    layout: &crate::layout::Layout,
    options: MarkerOptions,
) -> Result<MarkerOptions, crate::scenario::ScenarioError> {
    let range = crate::visibility::RangeAxes::default()
        .working_range(layout, crate::visibility::MaxHidden::default())?;
    Ok(match range {
        Some(range) => routed_for(options, layout, &range),
        None => options,
    })
}

/// The supports of [`marker_for_range`], as occluders for the visibility
/// model.
pub fn supports_for_range(
    layout: &crate::layout::Layout,
    options: &MarkerOptions,
    range: &crate::visibility::WorkingRange,
) -> Result<crate::visibility::Supports, GeometryError> {
    Ok(crate::visibility::Supports::new(
        marker_for_range(layout, options, range)?.occluders(),
    ))
}

/// The supports the search prices a candidate layout with, in the time a
/// search can afford per candidate: the pillars structure's routes for
/// every sphere in the order `export`'s router tries them, the first that
/// keeps clear of the other spheres and their cones taken without scoring
/// views. Each sphere has the cone under it and a support straight back
/// along the view to the base plate's inner face; where that would pass
/// within the clearance of another sphere, the same support slanted
/// 10–35° in 16 directions (towards the layout's middle first); failing
/// those, a link onto the nearest sphere behind. Same constants and
/// clearances as [`Router::pillars`]. The plate is left out: it lies behind
/// every sphere along the view, so it hides none from a camera in front.
/// No printability check is made (the search's constraints hold the gaps).
/// `export`, scoring the views of a range, may still find a route that
/// hides fewer of them, so a layout is priced no better than it prints.
pub fn straight_supports(
    centres: &[Vector3<f64>],
    sphere_diameter_mm: f64,
    options: &MarkerOptions,
) -> crate::visibility::Supports {
    let v = options.view.vector();
    let radius = 0.5 * sphere_diameter_mm;
    let strut_radius = 0.5 * options.strut_diameter_mm;
    let clearance = options.min_feature_mm;
    let blend = blend_radius(strut_radius, clearance);
    let growth = junction_growth(blend);
    let drop_length = (radius - strut_radius) / TEARDROP_HALF_ANGLE_DEG.to_radians().sin();
    let tips: Vec<Vector3<f64>> = centres.iter().map(|c| c + v * drop_length).collect();
    let depth = |p: &Vector3<f64>| p.dot(&v);
    let inner = tips.iter().map(depth).fold(f64::NEG_INFINITY, f64::max)
        + strut_radius
        + 2.0 * blend
        + clearance;
    let steepest = SUPPORT_SLANTS_DEG
        .iter()
        .fold(0.0f64, |m, &s| m.max(s))
        .to_radians();
    let clear_of = |i: usize, end: &Vector3<f64>, onto: Option<usize>| {
        (0..centres.len())
            .filter(|&k| k != i && Some(k) != onto)
            .all(|k| {
                segment_distance(&tips[i], end, &centres[k], &tips[k]) - radius - strut_radius
                    >= clearance + growth
            })
    };
    let kv = v.iamax();
    let unit = |k: usize| Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let (e1, e2) = (unit((kv + 1) % 3), unit((kv + 2) % 3));
    let centroid = centres.iter().sum::<Vector3<f64>>() / centres.len().max(1) as f64;
    let mut occluders = Vec::with_capacity(2 * centres.len());
    for (i, tip) in tips.iter().enumerate() {
        let inward = centroid - centres[i];
        let phi_inward = inward.dot(&e2).atan2(inward.dot(&e1));
        let slanted = SUPPORT_SLANTS_DEG.iter().flat_map(|&slant_deg| {
            let slant = slant_deg.to_radians();
            let azimuths = if slant_deg == 0.0 {
                1
            } else {
                SUPPORT_AZIMUTHS
            };
            (0..azimuths).map(move |a| {
                let step = a.div_ceil(2) as f64 * if a % 2 == 1 { 1.0 } else { -1.0 };
                let phi = phi_inward + std::f64::consts::TAU * step / azimuths as f64;
                let direction = v * slant.cos() + (e1 * phi.cos() + e2 * phi.sin()) * slant.sin();
                tip + direction * ((inner - depth(tip)) / slant.cos())
            })
        });
        let straight = tip + v * (inner - depth(tip));
        let end = if let Some(end) = slanted.into_iter().find(|end| clear_of(i, end, None)) {
            end
        } else {
            (0..centres.len())
                .filter(|&j| j != i)
                .filter_map(|j| {
                    let offset = centres[j] - tip;
                    let along = offset.dot(&v);
                    let across = (offset - v * along).norm();
                    (along > radius + strut_radius + 2.0 * blend
                        && across <= along * steepest.tan()
                        && clear_of(i, &centres[j], Some(j)))
                    .then_some((offset.norm(), centres[j]))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map_or(straight, |(_, c)| c)
        };
        occluders.push(Occluder::RoundCone {
            a: centres[i],
            radius_a: radius,
            b: *tip,
            radius_b: strut_radius,
        });
        occluders.push(Occluder::Capsule {
            a: *tip,
            b: end,
            radius: strut_radius,
        });
    }
    crate::visibility::Supports::new(occluders)
}
