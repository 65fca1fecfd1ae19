//! `export SET.json`: every marker of a set built with its number (1…N,
//! set order) engraved into its base plate ([`super::geometry::Engraving`]),
//! each part's files in a directory of its own, `<k>-<layout name>/`, and
//! one sheet for the set, `<set name>-set.md`, beside them.
//!
//! Every part is designed, meshed and checked before any file is written,
//! so a part that cannot be built leaves nothing behind. The files are
//! then written into a staging directory inside the output directory and
//! moved into place once all are there; a part's directory left by an
//! earlier export is replaced whole.

use super::analysis::{analyse_numbered, Analysis, ExportReport};
use super::workflow::{write_analysis, Target};
use super::{file_stem, write_file, ExportError, ExportOptions};
use crate::kernel::stop::abandon_on_stop;
use crate::kernel::OutputPlan;
use crate::observer::Observer;
use crate::set::MarkerSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Progress phase of a set export (one step per part designed, one per
/// part written).
pub const PHASE_SET_EXPORT: &str = "export set";

/// One part of an exported set.
#[derive(Debug, Clone)]
pub struct SetExportPart {
    /// Its number, engraved into its plate (1…N, set order).
    pub number: usize,
    /// Its layout file as the set file lists it.
    pub file: String,
    /// The directory its files went into.
    pub directory: PathBuf,
    /// Its export report (files named where they are now).
    pub report: ExportReport,
}

/// What [`export_set`] wrote.
#[derive(Debug, Clone)]
pub struct SetExportReport {
    /// The set's name.
    pub name: String,
    /// Every part, in set order.
    pub parts: Vec<SetExportPart>,
    /// The set's sheet.
    pub sheet: PathBuf,
}

/// A staging directory removed when dropped, with anything it holds.
struct Staging(PathBuf);

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> ExportError {
    let path = path.to_path_buf();
    move |source| ExportError::Io { path, source }
}

/// The directory name of part `number` of layout `name`.
pub fn part_directory(number: usize, name: &str) -> String {
    format!("{number}-{}", file_stem(name))
}

/// Builds every part of `set` with its number engraved and writes their
/// files and the set's sheet into `out_dir` (module docs). An observer
/// that asks to stop gets [`ExportError::Interrupted`] and no files.
pub fn export_set(
    set: &MarkerSet,
    options: &ExportOptions,
    out_dir: &Path,
    observer: &mut impl Observer,
) -> Result<SetExportReport, ExportError> {
    // The set's directory checked and locked before any work; the parts
    // are moved in as whole directories below.
    let mut plan = OutputPlan::new();
    plan.input("SET", &set.path).dir("--out", out_dir);
    let _outputs = plan.open()?;
    let total = 2 * set.members.len() as u64;
    let mut done = 0;
    observer.progress(PHASE_SET_EXPORT, done, total);
    let mut analyses: Vec<Analysis> = Vec::with_capacity(set.members.len());
    for (k, member) in set.members.iter().enumerate() {
        let number = k + 1;
        let (layout, part_options) = (member.layout.clone(), options.clone());
        let analysis = abandon_on_stop(observer, move || {
            analyse_numbered(&layout, &part_options, Some(&number.to_string()))
        })
        .map_err(|_| ExportError::Interrupted)?
        .map_err(|source| ExportError::SetPart {
            number,
            file: member.file.clone(),
            source: Box::new(source),
        })?;
        analyses.push(analysis);
        done += 1;
        observer.progress(PHASE_SET_EXPORT, done, total);
    }
    std::fs::create_dir_all(out_dir).map_err(io(out_dir))?;
    let stem = file_stem(&set.name);
    let staging = Staging(out_dir.join(format!(".{stem}.set-export.{}.tmp", std::process::id())));
    let _ = std::fs::remove_dir_all(&staging.0);
    std::fs::create_dir(&staging.0).map_err(io(&staging.0))?;
    let mut parts = Vec::with_capacity(analyses.len());
    for ((k, member), analysis) in set.members.iter().enumerate().zip(analyses) {
        let number = k + 1;
        let directory = part_directory(number, &member.layout.name);
        let observer_ref = &*observer;
        let part_dir = staging.0.join(&directory);
        let outputs = Target {
            dir: &part_dir,
            sources: &[],
        }
        .open()?;
        let mut report = write_analysis(analysis, options, &part_dir, outputs, &|| {
            observer_ref.interrupted()
        })?;
        for file in &mut report.files {
            if let Ok(rest) = file.path.strip_prefix(&staging.0) {
                file.path = out_dir.join(rest);
            }
        }
        parts.push(SetExportPart {
            number,
            file: member.file.clone(),
            directory: out_dir.join(&directory),
            report,
        });
        done += 1;
        observer.progress(PHASE_SET_EXPORT, done, total);
    }
    if observer.interrupted() {
        return Err(ExportError::Interrupted);
    }
    let sheet_name = format!("{stem}-set.md");
    let report = SetExportReport {
        name: set.name.clone(),
        parts,
        sheet: out_dir.join(&sheet_name),
    };
    write_file(
        &staging.0.join(&sheet_name),
        set_sheet(set, &report).as_bytes(),
    )?;
    for part in &report.parts {
        let name = part.directory.file_name().expect("a part directory");
        replace_directory(&staging.0.join(name), &part.directory)?;
    }
    let sheet_staged = staging.0.join(&sheet_name);
    std::fs::rename(&sheet_staged, &report.sheet).map_err(io(&report.sheet))?;
    Ok(report)
}

/// Moves directory `from` to `to`, replacing a directory already there
/// (moved aside first, removed once the new one is in place).
fn replace_directory(from: &Path, to: &Path) -> Result<(), ExportError> {
    if to.exists() {
        let name = to.file_name().expect("a named directory").to_string_lossy();
        let aside = to.with_file_name(format!(".{name}.old.{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&aside);
        std::fs::rename(to, &aside).map_err(io(to))?;
        std::fs::rename(from, to).map_err(io(to))?;
        let _ = std::fs::remove_dir_all(&aside);
    } else {
        std::fs::rename(from, to).map_err(io(to))?;
    }
    Ok(())
}

/// The set's sheet: one row per part with its number, layout file,
/// directory and its own sheet's main figures.
pub fn set_sheet(set: &MarkerSet, report: &SetExportReport) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Marker set: {}\n", set.name);
    let _ = writeln!(
        md,
        "Made by `layout-opt export` (version {}) from the set file {}. Each part's number is engraved into the face of its base plate beside the spheres (the face towards the camera for the printable structure); mount each part where its number says. All lengths in millimetres.\n",
        env!("CARGO_PKG_VERSION"),
        set.path.display()
    );
    let _ = writeln!(
        md,
        "| number | layout | layout file | directory | spheres | print size | volume, mm³ | identification margin | sphere-centre tolerance | fabrication sheet |\n|---:|---|---|---|---:|---|---:|---:|---:|---|"
    );
    for part in &report.parts {
        let r = &part.report;
        let directory = part
            .directory
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let sheet = r
            .files
            .iter()
            .filter_map(|f| f.path.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .find(|n| n.ends_with("-fabrication.md"))
            .unwrap_or_default();
        let tolerance = r
            .tolerances
            .centre
            .as_ref()
            .map_or("—".to_string(), |t| format!("±{:.3}", t.tolerance_mm));
        let [x, y, z] = r.print_size_mm;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {directory}/ | {} | {x:.1} × {y:.1} × {z:.1} | {:.0} | {:.3} | {tolerance} | [{sheet}]({directory}/{sheet}) |",
            part.number,
            r.name,
            part.file,
            r.main_view_coverage.len(),
            r.mesh.topology.signed_volume_mm3,
            r.identification_margin_mm,
        );
    }
    let _ = writeln!(md, "\n## Engraving\n");
    for part in &report.parts {
        if let Some(e) = &part.report.engraving {
            let _ = writeln!(
                md,
                "- part {}: \"{}\", {} mm deep, strokes {} mm wide, {:.1} × {:.1} mm{}",
                part.number,
                e.text,
                e.depth_mm,
                e.stroke_mm,
                e.size_mm[0],
                e.size_mm[1],
                if e.plate_grown {
                    " (plate lengthened to make room)"
                } else {
                    ""
                }
            );
        }
    }
    md
}
