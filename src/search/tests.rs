//! The evaluator's unit tests.

use super::*;
use crate::family::Envelope;
use crate::scenario::{Range, ScenarioGrid};

fn evaluator(objective: &str) -> Evaluator {
    let grid = ScenarioGrid::new(
        Range::list(&[300.0, 700.0]),
        Range::list(&[0.0, 60.0]),
        Range::single(0.0),
        Range::list(&[-40.0, 0.0, 40.0]),
        Range::single(0.0),
        Range::single(0.0),
        Range::single(0.5),
    )
    .unwrap();
    Evaluator::new(
        Camera::paper(),
        grid.scenarios(),
        ObjectiveSettings {
            objective: objective.parse().unwrap(),
            aggregate: Aggregate::Mean,
            translation_weight: 0.5,
            availability_weight: 2.0,
            min_availability: AvailabilityFloor::None,
            trials: 20,
            seed: 1,
            noise: NoiseModel::default(),
            observation: Observation::default(),
            chain: Default::default(),
        },
        Constraints {
            envelope: Envelope::new([100.0; 3]).unwrap(),
            sphere_diameter_mm: 10.0,
            min_gap_mm: 2.0,
            min_distance_diff_mm: 0.0,
        },
        &crate::synthetic::biprism_points(50.0),
    )
}

/// The identifiability floor: the symmetric paper biprism fails it in
/// every visible scenario (twins), pays a penalty and is not admissible;
/// a generic layout of the same size meets it at no cost; a scope of
/// chosen scenarios checks only those.
#[test]
fn the_identifiability_floor_rules_out_the_symmetric_biprism() {
    let plain = evaluator("crlb");
    let floor = Some(IdentifiabilityFloor::DEFAULT);
    let all = plain.with_identifiability(floor, IdentifyScope::All);
    let paper = crate::synthetic::biprism_points(50.0);
    let symmetric = all.evaluate(&paper, &[None; 7]);
    let figures = symmetric.identifiability.clone().unwrap();
    assert!(figures.all_checked);
    assert_eq!(figures.checked, symmetric.visible);
    assert_eq!(figures.identifiable, 0);
    assert_eq!(figures.twins, figures.checked);
    assert!(figures.penalty > 0.0 && !figures.meets_floor());
    assert!(!symmetric.admissible());
    let unchecked = plain.evaluate(&paper, &[None; 7]);
    assert!(unchecked.identifiability.is_none() && unchecked.admissible());
    assert!((symmetric.cost - unchecked.cost - figures.penalty).abs() < 1e-9);

    let generic = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(47.0, -6.0, 3.0),
        Vector3::new(-8.0, 38.0, -5.0),
        Vector3::new(-41.0, -12.0, 9.0),
        Vector3::new(7.0, 4.0, 45.0),
        Vector3::new(3.0, -44.0, -7.0),
        Vector3::new(-5.0, 9.0, -40.0),
    ];
    let good = all.evaluate(&generic, &[None; 7]);
    let figures = good.identifiability.clone().unwrap();
    assert_eq!(figures.identifiable, figures.checked, "{figures:?}");
    assert_eq!(figures.penalty, 0.0);
    assert!(good.admissible());

    let scoped = plain.with_identifiability(
        floor,
        IdentifyScope::Scenarios(std::sync::Arc::new(vec![0, 5])),
    );
    let some = scoped.evaluate(&paper, &[None; 7]);
    let figures = some.identifiability.unwrap();
    assert!(!figures.all_checked && figures.checked <= 2);
    assert!(figures.failing.iter().all(|k| [0, 5].contains(k)));
}

#[test]
fn the_reference_scores_one() {
    for objective in [
        "crlb",
        "transfer",
        "mc:ml",
        "crlb:0.5+mc:parallel-weighted:0.5",
    ] {
        let e = evaluator(objective);
        let score = e.evaluate(&crate::synthetic::biprism_points(50.0), &[None; 7]);
        let weights: f64 = e.settings().objective.terms.iter().map(|(_, w)| w).sum();
        assert!(
            (score.accuracy - weights).abs() < 1e-12,
            "{objective}: {}",
            score.accuracy
        );
    }
}

#[test]
fn a_smaller_marker_scores_worse() {
    let e = evaluator("crlb");
    let small: Vec<_> = crate::synthetic::biprism_points(25.0);
    let score = e.evaluate(&small, &[None; 7]);
    assert!(score.accuracy > 1.5, "{}", score.accuracy);
}

#[test]
fn objectives_parse() {
    assert_eq!(
        "crlb".parse::<Objective>().unwrap().terms,
        vec![(Term::Crlb, 1.0)]
    );
    assert_eq!(
        "mc:ml:0.3+transfer:0.7".parse::<Objective>().unwrap().terms,
        vec![(Term::MonteCarlo(Solver::Ml), 0.3), (Term::Transfer, 0.7)]
    );
    assert_eq!(
        "mc".parse::<Objective>().unwrap().terms,
        vec![(Term::MonteCarlo(Solver::ParallelWeighted), 1.0)]
    );
    assert!("mc:nope".parse::<Objective>().is_err());
    assert_eq!(
        "crlb:-1".parse::<Objective>().unwrap_err(),
        ObjectiveError::BadWeight(-1.0)
    );
    assert_eq!(
        "crlb:0.5+mc:ml:0.5"
            .parse::<Objective>()
            .unwrap()
            .to_string(),
        "crlb:0.5+mc:ml:0.5"
    );
}

/// A printed chain reads projected centres (no ellipse bias) and adds
/// the part's covariance: with a vanishing σ it scores the centre
/// observation exactly; a characterised part lies between the ideal
/// part and a printed one.
#[test]
fn the_chain_adds_the_parts_error_and_reads_projected_centres() {
    let base = evaluator("crlb");
    let points = crate::synthetic::biprism_points(50.0);
    let rotation = |chain: Chain, observation: Observation| {
        let e = Evaluator::new(
            base.camera,
            base.scenarios.clone(),
            ObjectiveSettings {
                chain,
                observation,
                ..base.settings.clone()
            },
            base.constraints,
            &points,
        );
        e.evaluate(&points, &[None; 7]).terms[0]
            .rotation_deg
            .unwrap()
    };
    let centre = rotation(Chain::Ideal, Observation::Centre);
    let ellipse = rotation(Chain::Ideal, Observation::EllipseCentre);
    assert!(ellipse > centre, "{ellipse} vs {centre}");
    let tiny = rotation(
        Chain::Printed { sigma_mm: 1e-9 },
        Observation::EllipseCentre,
    );
    assert!((tiny / centre - 1.0).abs() < 1e-9, "{tiny} vs {centre}");
    let printed = rotation(Chain::Printed { sigma_mm: 0.1 }, Observation::EllipseCentre);
    let characterised = rotation(
        Chain::Characterised { sigma_px: 0.02 },
        Observation::EllipseCentre,
    );
    assert!(printed > 1.01 * centre, "{printed} vs {centre}");
    assert!(
        characterised > centre && characterised < printed,
        "{characterised} between {centre} and {printed}"
    );
}

#[test]
fn the_floor_is_the_references_availability_and_only_binds_below_it() {
    let mut e = evaluator("crlb");
    e = Evaluator::new(
        e.camera,
        e.scenarios.clone(),
        ObjectiveSettings {
            min_availability: AvailabilityFloor::Reference,
            availability_weight: 0.0,
            ..e.settings.clone()
        },
        e.constraints,
        &crate::synthetic::biprism_points(50.0),
    );
    let paper = crate::synthetic::biprism_points(50.0);
    let score = e.evaluate(&paper, &[None; 7]);
    assert_eq!(e.availability_floor(), Some(score.availability));
    assert!(
        score.availability < 1.0,
        "the grid must cost the biprism views"
    );
    assert!(score.meets_availability_floor());
    assert_eq!(score.floor_penalty, 0.0);
    assert_eq!(score.objective, score.accuracy);
    let strict = e.with_floor(Some(1.0));
    let below = strict.evaluate(&paper, &[None; 7]);
    assert!(!below.meets_availability_floor() && !below.admissible());
    assert!(
        below.floor_penalty >= AVAILABILITY_PENALTY * (1.0 - below.availability),
        "{}",
        below.floor_penalty
    );
    assert_eq!(below.cost, score.cost + below.floor_penalty);
    assert_eq!(
        e.with_floor(None)
            .evaluate(&paper, &[None; 7])
            .floor_penalty,
        0.0
    );
}

#[test]
fn floors_parse() {
    assert_eq!("reference".parse(), Ok(AvailabilityFloor::Reference));
    assert_eq!("none".parse(), Ok(AvailabilityFloor::None));
    assert_eq!("0.6".parse(), Ok(AvailabilityFloor::Share(0.6)));
    assert_eq!("60%".parse(), Ok(AvailabilityFloor::Share(0.6)));
    assert!(matches!(
        "1.5".parse::<AvailabilityFloor>(),
        Err(ObjectiveError::BadFloor(_))
    ));
    assert!("most".parse::<AvailabilityFloor>().is_err());
}

#[test]
fn every_term_keeps_books_and_a_blend_scores_one_subset() {
    let e = evaluator("crlb:0.5+transfer:0.5");
    // A layout whose transfer model cannot use every scenario: a flat one.
    for points in [
        crate::synthetic::biprism_points(50.0),
        crate::synthetic::biprism_points(20.0),
    ] {
        let score = e.evaluate(&points, &[None; 7]);
        let usable = score.in_front - score.unusable_noise;
        assert_eq!(score.behind + score.in_front, e.scenarios().len());
        for term in &score.terms {
            assert_eq!(term.evaluated + term.failed, usable, "{term:?}");
            assert!(score.scored <= term.evaluated);
        }
        // Neither term fails on more scenarios than the other leaves out.
        let failed: usize = score.terms.iter().map(|t| t.failed).sum();
        assert!(score.scored + failed >= usable);
    }
}

#[test]
fn aggregates() {
    assert_eq!(Aggregate::Max.apply(&mut [1.0, 3.0, 2.0]), Some(3.0));
    assert_eq!(
        Aggregate::Mean.apply(&mut [3.0, 4.0]),
        Some((12.5f64).sqrt())
    );
    assert_eq!(Aggregate::P95.apply(&mut [1.0, 2.0]), Some(2.0));
    assert_eq!(Aggregate::Mean.apply(&mut []), None);
}
