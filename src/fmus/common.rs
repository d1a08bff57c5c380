//! What the muscle FMUs share: units and [`info_for`], the substep tolerance, range checks
//! of a restored state (the shared variable rows are in [`super::table`]).

use crate::fmi2::{ModelError, ModelInfo, Unit};
use crate::law::hill_fibre::FibreHistory;
use crate::law::params::{out_of_range, Range};
use crate::scene::SceneSpec;

/// Tolerance of both models' substep control (`substep_tolerance`'s
/// default), relative to sigma0: the estimated local error of the CE–SEE
/// update over one substep, as SEE stress, stays below `SUBSTEP_RTOL ·
/// sigma0` ([`crate::law::hill_fibre::backward_euler_error`]).
pub const SUBSTEP_RTOL: f64 = 1e-3;

/// The tolerances `substep_tolerance` accepts (a fraction of sigma0).
pub const SUBSTEP_TOLERANCE_RANGE: Range = Range {
    min: 1e-9,
    max: 1.0,
};

/// The refusal of a directional derivative of `stiffness`, itself
/// d force / d length (docs/reference/conventions.md).
pub fn stiffness_not_differentiated() -> ModelError {
    ModelError("stiffness is itself d force / d length: its derivatives are not provided".into())
}

/// The units both muscle FMUs declare.
pub fn units() -> Vec<Unit> {
    let u = |name, kg, m, s| Unit { name, kg, m, s };
    vec![
        u("1", 0, 0, 0),
        u("m", 0, 1, 0),
        u("m2", 0, 2, 0),
        u("s", 0, 0, 1),
        u("1/s", 0, 0, -1),
        u("N", 1, 1, -2),
        u("Pa", 1, -1, -2),
        u("1/Pa", -1, 1, 2),
    ]
}

/// The [`ModelInfo`] of the muscle FMU of scene `spec`: its identifier,
/// description and DefaultExperiment, the [`units`]; the unit N/m only when
/// the scene exposes `stiffness` (so the full FMUs' interfaces, and GUIDs,
/// are unchanged).
pub fn info_for(spec: &SceneSpec) -> ModelInfo {
    let mut units = units();
    if spec.outputs.contains(&"stiffness") {
        units.push(Unit {
            name: "N/m",
            kg: 1,
            m: 0,
            s: -2,
        });
    }
    ModelInfo {
        model_identifier: spec.model_identifier,
        description: spec.description,
        version: env!("CARGO_PKG_VERSION"),
        units,
        default_experiment: spec.default_experiment,
        max_input_derivative_order: 1,
        direct_feedthrough: false,
    }
}

/// `v` in `range`, else an error naming `name` and the range.
pub fn check_range(name: &str, v: f64, range: Range) -> Result<(), ModelError> {
    range.check(name, v).map_err(ModelError)
}

/// `v` in [0, 1], else an error naming `name`.
pub fn check_unit_interval(name: &str, v: f64) -> Result<(), ModelError> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(ModelError(out_of_range(name, v, "in [0, 1]")))
    }
}

/// A restored FMU state's drive, as strict as the calls that set it: the
/// activation command (clamped into [0, 1] when set) and the activation
/// level (MODEL_NOTES "Activation dynamics": it stays in [0, 1]) in [0, 1].
pub fn check_restored_drive(command: f64, activation_level: f64) -> Result<(), ModelError> {
    check_unit_interval("activation", command)?;
    check_unit_interval("activation level", activation_level)
}

/// A restored FMU state's fibre histories: every committed CE and SEE
/// stretch finite and > 0, as the CE–SEE update leaves them (it refuses a
/// step that would make one non-positive, [`FibreHistory::check_physical`]).
pub fn check_restored_history(histories: &[FibreHistory]) -> Result<(), ModelError> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    match histories
        .iter()
        .position(|h| !(positive(h.lambda_m) && positive(h.lambda_s)))
    {
        None => Ok(()),
        Some(i) => Err(ModelError(format!(
            "fibre history {i}: CE stretch {} and SEE stretch {} must be finite and > 0",
            histories[i].lambda_m, histories[i].lambda_s
        ))),
    }
}

/// Test support for both models' restore checks: `m` serialized and
/// deserialized again ([`Model::serialize`], [`Model::deserialize`]).
#[cfg(test)]
pub fn restored<M: crate::fmi2::Model>(m: &M) -> Result<M, ModelError> {
    let mut bytes = Vec::new();
    m.serialize(&mut bytes);
    M::deserialize(&mut bytes.as_slice())
}

/// Test support: a copy of `m` changed by `forge` (a crafted state) is
/// refused on restore, with a message that contains `what`.
#[cfg(test)]
pub fn assert_restore_refuses<M: crate::fmi2::Model + Clone>(
    m: &M,
    forge: impl Fn(&mut M),
    what: &str,
) {
    let mut f = m.clone();
    forge(&mut f);
    match restored(&f) {
        Ok(_) => panic!("a state with {what} was accepted"),
        Err(e) => assert!(e.0.contains(what), "{what}: {}", e.0),
    }
}
