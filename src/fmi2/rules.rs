//! FMI 2.0 rules on scalar variables (FMI 2.0 spec, section 2.2.7
//! "Definition of Model Variables"): valid causality/variability/initial
//! combinations, the default of `initial`, and which variables an importer
//! may set in which state (the footnotes of the state tables of sections
//! 3.2.3 and 4.2.4).

use super::model::{Causality, Initial, ScalarVariable, VarType, Variability};
use super::state::{FmiState, StateSet};

/// The value type of a variable (what `fmi2GetReal`, `fmi2GetInteger`, ...
/// may access).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueKind {
    Real,
    Integer,
    Boolean,
}

impl ValueKind {
    pub fn of(ty: &VarType) -> Self {
        match ty {
            VarType::Real { .. } => ValueKind::Real,
            VarType::Integer { .. } => ValueKind::Integer,
            VarType::Boolean { .. } => ValueKind::Boolean,
        }
    }
}

/// What the get and set functions need to know of one variable on their
/// hot path, computed once per instance from the variable table (the rules
/// of this module evaluated for every state), so that checking a value
/// reference is a table look-up and two comparisons.
#[derive(Clone, Copy, Debug)]
pub struct Dispatch<V> {
    /// The model's handle ([`ScalarVariable::id`]).
    pub id: V,
    pub kind: ValueKind,
    /// The states in which the importer may set it ([`settable_in`]).
    pub settable: StateSet,
    /// [`is_computed`].
    pub computed: bool,
}

impl<V: Copy> Dispatch<V> {
    pub fn of(v: &ScalarVariable<V>) -> Self {
        Dispatch {
            id: v.id,
            kind: ValueKind::of(&v.ty),
            settable: StateSet::filter(|s| settable_in(v, s)),
            computed: is_computed(v),
        }
    }
}

/// The `initial` attribute in force: the given one or the default of the
/// FMI 2.0 table in section 2.2.7 for the causality/variability pair.
/// `None` for `independent` (no `initial` and no start value allowed).
/// Inputs have no `initial` attribute in the XML; like the FMI Library we
/// treat them as `approx` (the start value is only used until the importer
/// sets the input).
pub fn effective_initial<V>(v: &ScalarVariable<V>) -> Option<Initial> {
    if v.initial.is_some() {
        return v.initial;
    }
    use Causality as C;
    use Variability as Va;
    match (v.causality, v.variability) {
        (C::Independent, _) => None,
        (C::Input, _) => Some(Initial::Approx),
        (C::Parameter, _) => Some(Initial::Exact),
        (_, Va::Constant) => Some(Initial::Exact),
        _ => Some(Initial::Calculated),
    }
}

/// Whether the causality/variability pair is one of the valid combinations of
/// the FMI 2.0 table in section 2.2.7 (and `continuous` only for Real).
pub fn combination_valid<V>(v: &ScalarVariable<V>) -> Result<(), String> {
    use Causality as C;
    use Variability as Va;
    let ok = match v.causality {
        C::Parameter | C::CalculatedParameter => {
            matches!(v.variability, Va::Fixed | Va::Tunable)
        }
        C::Input => matches!(v.variability, Va::Discrete | Va::Continuous),
        C::Output => matches!(v.variability, Va::Constant | Va::Discrete | Va::Continuous),
        C::Local => true,
        C::Independent => v.variability == Va::Continuous,
    };
    if !ok {
        return Err(format!(
            "causality {} with variability {} is not allowed (FMI 2.0 section 2.2.7)",
            causality_name(v.causality),
            variability_name(v.variability)
        ));
    }
    if v.variability == Va::Continuous && !matches!(v.ty, VarType::Real { .. }) {
        return Err("variability continuous is only allowed for Real variables".into());
    }
    if v.causality == C::Independent && !matches!(v.ty, VarType::Real { .. }) {
        return Err("the independent variable must be Real".into());
    }
    // Allowed explicit `initial` values (FMI 2.0 section 2.2.7 table).
    if let Some(i) = v.initial {
        let allowed: &[Initial] = match (v.causality, v.variability) {
            (C::Independent, _) | (C::Input, _) => &[],
            (C::Parameter, _) | (_, Va::Constant) => &[Initial::Exact],
            (C::CalculatedParameter, _) | (C::Local, Va::Fixed | Va::Tunable) => {
                &[Initial::Calculated, Initial::Approx]
            }
            _ => &[Initial::Exact, Initial::Approx, Initial::Calculated],
        };
        if !allowed.contains(&i) {
            return Err(format!(
                "initial = {} is not allowed for causality {} / variability {}",
                initial_name(i),
                causality_name(v.causality),
                variability_name(v.variability)
            ));
        }
    }
    Ok(())
}

/// Whether the importer may call `fmi2Set{Real,Integer,Boolean}` on `v` in
/// `state` (FMI 2.0 spec, section 4.2.4 state table, footnotes on
/// fmi2SetXXX):
///
/// - `instantiated`: variability != constant and initial = exact or approx;
/// - `initializationMode`: variability != constant and initial = exact, or
///   causality = input;
/// - `stepComplete`: causality = input, or causality = parameter with
///   variability = tunable.
///
/// Additionally only inputs and parameters are ever forwarded to the model
/// (the [`Model`](super::Model) contract), so e.g. a local with
/// `initial = "approx"` is not settable through this layer.
pub fn settable_in<V>(v: &ScalarVariable<V>, state: FmiState) -> bool {
    if !matches!(v.causality, Causality::Input | Causality::Parameter) {
        return false;
    }
    let not_constant = v.variability != Variability::Constant;
    let initial = effective_initial(v);
    match state {
        FmiState::Instantiated => {
            not_constant && matches!(initial, Some(Initial::Exact | Initial::Approx))
        }
        FmiState::InitializationMode => {
            (not_constant && initial == Some(Initial::Exact)) || v.causality == Causality::Input
        }
        FmiState::StepComplete => {
            v.causality == Causality::Input
                || (v.causality == Causality::Parameter && v.variability == Variability::Tunable)
        }
        _ => false,
    }
}

/// Whether `v` is a value the model computes (outputs, calculated parameters,
/// locals): reading it in initialization mode after a set needs
/// [`Model::initialize`](super::Model::initialize) first.
pub fn is_computed<V>(v: &ScalarVariable<V>) -> bool {
    !matches!(
        v.causality,
        Causality::Input | Causality::Parameter | Causality::Independent
    ) && v.variability != Variability::Constant
}

pub fn causality_name(c: Causality) -> &'static str {
    match c {
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Local => "local",
        Causality::Independent => "independent",
    }
}

pub fn variability_name(v: Variability) -> &'static str {
    match v {
        Variability::Constant => "constant",
        Variability::Fixed => "fixed",
        Variability::Tunable => "tunable",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    }
}

pub fn initial_name(i: Initial) -> &'static str {
    match i {
        Initial::Exact => "exact",
        Initial::Approx => "approx",
        Initial::Calculated => "calculated",
    }
}

/// "Real", "Integer" or "Boolean".
pub fn type_name(t: &VarType) -> &'static str {
    match t {
        VarType::Real { .. } => "Real",
        VarType::Integer { .. } => "Integer",
        VarType::Boolean { .. } => "Boolean",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-instance dispatch table says what the rules say, for every
    /// causality, variability, `initial` and value type, in every state.
    #[test]
    fn dispatch_agrees_with_the_rules() {
        use Causality as C;
        use Variability as V;
        let types = [
            VarType::Real {
                unit: None,
                start: Some(0.0),
                min: None,
                max: None,
            },
            VarType::Integer {
                start: Some(0),
                min: None,
                max: None,
            },
            VarType::Boolean { start: Some(false) },
        ];
        let mut n = 0;
        for causality in [
            C::Parameter,
            C::CalculatedParameter,
            C::Input,
            C::Output,
            C::Local,
            C::Independent,
        ] {
            for variability in [
                V::Constant,
                V::Fixed,
                V::Tunable,
                V::Discrete,
                V::Continuous,
            ] {
                for initial in [
                    None,
                    Some(Initial::Exact),
                    Some(Initial::Approx),
                    Some(Initial::Calculated),
                ] {
                    for ty in &types {
                        let v = ScalarVariable {
                            name: "v",
                            description: "",
                            causality,
                            variability,
                            initial,
                            ty: *ty,
                            depends_on: vec![],
                            id: n,
                        };
                        let d = Dispatch::of(&v);
                        assert_eq!(d.id, n);
                        assert_eq!(d.kind, ValueKind::of(ty));
                        assert_eq!(d.computed, is_computed(&v));
                        for s in FmiState::ALL {
                            assert_eq!(
                                d.settable.contains(s),
                                settable_in(&v, s),
                                "{v:?} in {s:?}"
                            );
                        }
                        n += 1;
                    }
                }
            }
        }
        assert_eq!(n, 6 * 5 * 4 * 3);
    }
}
