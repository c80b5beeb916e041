//! The JSON record of a comparison (`compare.json`): every raw measurement with its unit,
//! the scores derived from them, the references and the settings, so anybody can re-derive
//! the table.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// One measured quantity, or why it could not be measured.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Measure {
    /// The value in `unit`; `None` when the model could not do the scenario.
    pub value: Option<f64>,
    pub unit: String,
    /// Why there is no value ("cannot cut", "diverged at dt = 1e-3 s"), or a caveat on it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

impl Measure {
    pub fn of(value: f64, unit: &str) -> Self {
        // A non-finite number is a failure, never a silent value.
        if value.is_finite() {
            Self {
                value: Some(value),
                unit: unit.into(),
                note: None,
            }
        } else {
            Self::failed(unit, format!("not finite ({value})"))
        }
    }

    pub fn failed(unit: &str, reason: impl Into<String>) -> Self {
        Self {
            value: None,
            unit: unit.into(),
            note: Some(reason.into()),
        }
    }

    pub fn noted(mut self, note: impl Into<String>) -> Self {
        self.note = Some(note.into());
        self
    }
}

/// A curve (probe force against indentation, volume against compression...).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Curve {
    pub x_unit: String,
    pub y_unit: String,
    pub points: Vec<[f64; 2]>,
}

/// Everything measured on one model kind.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct KindRecord {
    pub kind: String,
    /// The survey's column, or our note for kinds it has none for.
    pub column: String,
    /// Set when the model could not even be built: every cell then carries this reason.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub build_error: Option<String>,
    /// Raw measurements by name (see `docs/compare.md`).
    pub measures: BTreeMap<String, Measure>,
    /// Curves by name: "indentation" (force against depth), "compression" (volume change
    /// against plate travel), "cost" (s per simulated ms against elements).
    pub curves: BTreeMap<String, Curve>,
    /// Wall time spent measuring this kind, in s.
    pub wall_seconds: f64,
}

/// One score cell of Table 1.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// Criterion key (`survey::CRITERIA`).
    pub criterion: String,
    /// 0 to the criterion's weight.
    pub score: f64,
    /// The measured values the score comes from, as shown in the table.
    pub shown: String,
    /// The survey's score for the kind's column, if it has one.
    pub survey: Option<f64>,
}

/// A kind's row of scores.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct KindScores {
    pub kind: String,
    pub cells: Vec<Cell>,
    /// Group totals in `survey::GROUPS` order, then the overall total.
    pub groups: [f64; 3],
    pub total: f64,
    pub survey_groups: Option<[f64; 3]>,
    pub survey_total: Option<f64>,
}

/// The reference solution and its convergence check.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceRecord {
    pub model: String,
    /// Per refinement level: tetrahedra, nodes, shallow probe force (N).
    pub levels: Vec<ReferenceLevel>,
    /// Relative change of the probe force between the two finest levels.
    pub convergence: f64,
    pub measures: BTreeMap<String, Measure>,
    pub curves: BTreeMap<String, Curve>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceLevel {
    pub tets: usize,
    pub nodes: usize,
    pub probe_force: f64,
    pub build_seconds: f64,
    /// Surface vertices the probe held at the end.
    #[serde(default)]
    pub contacts: usize,
    /// False when the static contact loop stopped at its cap at some increment.
    #[serde(default)]
    pub contact_converged: bool,
    /// Wall time of the indentation (the increments and their contact loops), s.
    #[serde(default)]
    pub solve_seconds: f64,
    /// Numeric factorisations the indentation took.
    #[serde(default)]
    pub factorizations: usize,
}

/// The whole comparison.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CompareRecord {
    /// `tissue` version that measured it.
    pub version: String,
    /// The command line.
    pub command: String,
    pub organ: String,
    pub settings: super::Settings,
    pub scenario: super::Scenario,
    pub reference: ReferenceRecord,
    pub kinds: Vec<KindRecord>,
    pub scores: Vec<KindScores>,
    pub wall_seconds: f64,
}
