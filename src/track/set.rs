//! `track --set`: frames that may show several markers of one set. The
//! blobs of a frame are grouped into markers by the best joint fit
//! ([`crate::set::group_blobs`], as `solve --unlabelled --set` does); each
//! group is then tracked as a frame of that marker alone (identification,
//! pose, covariance and label trust, [`super::analysis`]), and named by its
//! number in the set (1…N) and its layout's name.

use super::analysis::{
    locate, max_blobs, projected_centre_normalised, FrameAnalysis, TrackedFrame,
};
use super::config::TrackConfig;
use super::detect::{detect, Blob, Detection, Misshapen, Rejected};
use super::frame::GreyFrame;
use super::refine::Refiner;
use crate::config::ConfigError;
use crate::pnp::unlabelled::UnlabelledOptions;
use crate::set::grouping;
use nalgebra::Vector2;
use serde::Serialize;

/// The markers of a set, each with its tracking configuration (one camera,
/// one detector: the first marker's).
#[derive(Debug, Clone)]
pub struct SetTrackConfig {
    /// (layout name, configuration) per marker, in set order.
    pub markers: Vec<(String, TrackConfig)>,
    /// One render-and-compare refiner per marker, in set order
    /// ([`super::refine`]), or none. Each marker found is refined with its
    /// own part alone: the other markers are not drawn.
    pub refiners: Option<Vec<Refiner>>,
}

impl SetTrackConfig {
    /// Checks every marker's configuration, and that they share the
    /// camera and the sphere diameter.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let Some((_, first)) = self.markers.first() else {
            return Err(ConfigError::new("markers", "a set has markers"));
        };
        if let Some(refiners) = &self.refiners {
            if refiners.len() != self.markers.len() {
                return Err(ConfigError::new("refine", "one refiner per marker"));
            }
            for refiner in refiners {
                refiner.check(first)?;
            }
        }
        for (_, config) in &self.markers {
            config.validate()?;
            if config.sphere_diameter_mm != first.sphere_diameter_mm {
                return Err(ConfigError::new(
                    "sphere_diameter_mm",
                    "the markers of a set share one sphere diameter",
                ));
            }
        }
        Ok(())
    }
}

/// One marker found in a frame.
#[derive(Debug)]
pub struct MarkerTrack {
    /// Its number in the set (1…N).
    pub number: usize,
    /// Its layout's name.
    pub layout: String,
    /// Its blobs, labels and pose, as a frame of that marker alone.
    pub analysis: FrameAnalysis,
}

/// A frame of a set: the markers found, or why none was.
#[derive(Debug)]
pub struct SetFrameAnalysis {
    /// Every marker found, in set order.
    pub markers: Vec<MarkerTrack>,
    /// Why no marker was found (detection failed, or no group fits).
    pub error: Option<String>,
    /// Every blob the detector accepted.
    pub blobs: Vec<Blob>,
    /// The blobs (indices into `blobs`) that no marker found explains:
    /// clutter, the blobs of a marker that could not be posed, and those
    /// flagged as partly hidden, such as two spheres of different markers
    /// whose discs touch and merge into one blob.
    pub unclaimed: Vec<usize>,
    /// The components rejected as no sphere's disc, where they are (two
    /// discs that merged and could not be parted).
    pub misshapen: Vec<Misshapen>,
}

impl SetFrameAnalysis {
    /// A frame with no marker and no blob, for `error` (a frame that could
    /// not be read).
    pub fn unread(error: String) -> Self {
        SetFrameAnalysis {
            markers: Vec::new(),
            error: Some(error),
            blobs: Vec::new(),
            unclaimed: Vec::new(),
            misshapen: Vec::new(),
        }
    }
}

/// Tracks every marker of the set in one frame (module docs). `config`
/// must have been validated.
pub fn analyse_set(config: &SetTrackConfig, frame: &GreyFrame) -> SetFrameAnalysis {
    let first = &config.markers[0].1;
    let spheres: usize = config.markers.iter().map(|(_, c)| c.object.len()).sum();
    let max_blobs = max_blobs(spheres, first.max_extra_blobs);
    let failed = |error: String, blobs: Vec<Blob>| SetFrameAnalysis {
        markers: Vec::new(),
        error: Some(error),
        unclaimed: (0..blobs.len()).collect(),
        blobs,
        misshapen: Vec::new(),
    };
    let detection = match detect(
        frame,
        &first.camera,
        &first.detector,
        first.radius_mm(),
        max_blobs,
    ) {
        Ok(detection) => detection,
        Err(error) => return failed(error.to_string(), Vec::new()),
    };
    let usable: Vec<usize> = (0..detection.blobs.len())
        .filter(|&i| !detection.blobs[i].hidden())
        .collect();
    let image: Vec<Vector2<f64>> = usable
        .iter()
        .map(|&i| projected_centre_normalised(&detection.blobs[i], first.centre))
        .collect();
    let focal = first.camera.fx().min(first.camera.fy());
    let options = UnlabelledOptions::with_gate_px(first.gate_px, focal, 1);
    let objects: Vec<_> = config
        .markers
        .iter()
        .map(|(_, c)| c.object.clone())
        .collect();
    let grouping = grouping(&objects, &image, &options);
    let mut markers = Vec::new();
    let mut errors: Vec<String> = grouping
        .ambiguous
        .iter()
        .map(|(better, rival, blobs)| {
            format!(
                "markers {} and {} both fit {} blobs about as well: neither is named",
                better + 1,
                rival + 1,
                blobs.len()
            )
        })
        .collect();
    let placements = grouping.placements;
    let mut claimed = vec![false; detection.blobs.len()];
    for placement in placements {
        let (layout, marker_config) = &config.markers[placement.marker];
        let mut blobs: Vec<Blob> = placement
            .blobs
            .iter()
            .map(|&k| detection.blobs[usable[k]].clone())
            .collect();
        let rejected = detection.rejected;
        let mut analysis = match locate(marker_config, &mut blobs, &rejected) {
            Ok((tracked, pose)) => FrameAnalysis {
                outcome: Ok(tracked),
                detection: Some(Detection {
                    blobs,
                    rejected,
                    threshold: detection.threshold,
                    threshold_level: detection.threshold_level,
                    misshapen: detection.misshapen.clone(),
                }),
                pose: Some(pose),
            },
            Err(error) => {
                errors.push(format!("marker {}: {error}", placement.marker + 1));
                continue;
            }
        };
        if let Some(refiners) = &config.refiners {
            analysis = refiners[placement.marker].refine(marker_config, frame, analysis);
            if let Err(error) = &analysis.outcome {
                errors.push(format!("marker {}: {error}", placement.marker + 1));
                continue;
            }
        }
        for &k in &placement.blobs {
            claimed[usable[k]] = true;
        }
        markers.push(MarkerTrack {
            number: placement.marker + 1,
            layout: layout.clone(),
            analysis,
        });
    }
    let error = markers.is_empty().then(|| {
        if errors.is_empty() {
            format!(
                "no marker of the set fits the {} usable blobs",
                usable.len()
            )
        } else {
            errors.join("; ")
        }
    });
    SetFrameAnalysis {
        markers,
        error,
        unclaimed: (0..claimed.len()).filter(|&i| !claimed[i]).collect(),
        blobs: detection.blobs,
        misshapen: detection.misshapen,
    }
}

/// One JSON line of `track --set`: a marker found in a frame, or a frame
/// with none.
#[derive(Debug, Serialize)]
#[serde(untagged)]
pub enum SetRecord<'a> {
    /// A marker with a pose.
    Tracked {
        /// The frame's name.
        frame: &'a str,
        /// The marker's number in the set (1…N).
        marker: usize,
        /// Its layout's name.
        layout: &'a str,
        /// The pose fields, as `track` writes them for one marker.
        #[serde(flatten)]
        tracked: &'a TrackedFrame,
        /// The blobs of this marker.
        blobs: &'a [Blob],
        /// Components rejected in the frame, by reason.
        rejected: &'a Rejected,
        /// The frame's blobs that no marker found explains
        /// ([`SetFrameAnalysis::unclaimed`]).
        unclaimed_blobs: Vec<&'a Blob>,
        /// The frame's components rejected as no sphere's disc.
        misshapen: &'a [Misshapen],
    },
    /// A frame in which no marker was found.
    Failed {
        /// The frame's name.
        frame: &'a str,
        /// Why.
        error: &'a str,
        /// Every blob the detector accepted.
        blobs: &'a [Blob],
        /// The frame's components rejected as no sphere's disc.
        misshapen: &'a [Misshapen],
    },
}

/// The records of one frame: one per marker found, or one failure.
pub fn set_records<'a>(name: &'a str, analysis: &'a SetFrameAnalysis) -> Vec<SetRecord<'a>> {
    let mut records = Vec::new();
    for marker in &analysis.markers {
        if let (Ok(tracked), Some(detection)) =
            (&marker.analysis.outcome, &marker.analysis.detection)
        {
            records.push(SetRecord::Tracked {
                frame: name,
                marker: marker.number,
                layout: &marker.layout,
                tracked,
                blobs: &detection.blobs,
                rejected: &detection.rejected,
                unclaimed_blobs: analysis
                    .unclaimed
                    .iter()
                    .map(|&i| &analysis.blobs[i])
                    .collect(),
                misshapen: &analysis.misshapen,
            });
        }
    }
    if records.is_empty() {
        records.push(SetRecord::Failed {
            frame: name,
            error: analysis.error.as_deref().unwrap_or("no marker found"),
            blobs: &analysis.blobs,
            misshapen: &analysis.misshapen,
        });
    }
    records
}

/// The JSON-lines document of every frame, in input order.
pub fn set_json_lines(frames: &[(String, SetFrameAnalysis)]) -> String {
    let mut out = String::new();
    for (name, analysis) in frames {
        for record in set_records(name, analysis) {
            out.push_str(&serde_json::to_string(&record).expect("records serialise"));
            out.push('\n');
        }
    }
    out
}
