//! Directional derivatives and input/output derivatives (FMI 2.0 spec,
//! sections 2.1.9 and 4.2.1).

use super::*;

/// What a known of [`get_directional_derivative`] is: an input, or a
/// parameter (initialization mode only) with its declared range.
#[derive(Clone, Copy)]
enum Known {
    Input,
    Parameter { min: Option<f64>, max: Option<f64> },
}

/// `fmi2GetDirectionalDerivative` (FMI 2.0 spec, section 2.1.9):
/// `dvUnknown[i] = Σ_j ∂unknown_i/∂known_j · dvKnown[j]`. Unknowns must be
/// Real outputs. Knowns are Real inputs, with the partial derivatives from
/// [`Model::partial_derivative`], and in initialization mode also Real
/// parameters (the knowns of `<InitialUnknowns>`, section 2.2.8), with the
/// partial derivatives of the initial values from
/// [`initial_parameter_column`] (0 where the unknown's `depends_on` does not
/// name the parameter).
///
/// # Safety
/// `c` a live instance; arrays of the given lengths.
#[allow(clippy::too_many_arguments)]
pub unsafe fn get_directional_derivative<M: Model>(
    c: fmi2Component,
    v_unknown_ref: *const fmi2ValueReference,
    n_unknown: usize,
    v_known_ref: *const fmi2ValueReference,
    n_known: usize,
    dv_known: *const fmi2Real,
    dv_unknown: *mut fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2GetDirectionalDerivative";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_DIRECTIONAL_DERIVATIVE, |inst| {
            let unknowns = in_slice(&inst.log, F, "vUnknown_ref", v_unknown_ref, n_unknown)?;
            let knowns = in_slice(&inst.log, F, "vKnown_ref", v_known_ref, n_known)?;
            let dv_k = in_slice(&inst.log, F, "dvKnown", dv_known, n_known)?;
            if let Some(i) = dv_k.iter().position(|d| !d.is_finite()) {
                inst.log.error(&format!(
                    "{F}: dvKnown[{i}] = {:?} must be finite (a seed of the known variables)",
                    dv_k[i]
                ));
                return Err(fmi2Error);
            }
            let dv_u = out_slice(&inst.log, F, "dvUnknown", dv_unknown, n_unknown)?;
            let initializing = inst.layer.fmi_state == FmiState::InitializationMode;
            let refuse =
                |v: &ScalarVariable<M::Var>, vr: fmi2ValueReference, role: &str, rule: &str| {
                    inst.log.error(&format!(
                        "{F}: '{}' (value reference {vr}, {} {}) cannot be {role}: {rule}",
                        v.name,
                        type_name(&v.ty),
                        causality_name(v.causality)
                    ));
                    fmi2Error
                };
            let u_ids = unknowns
                .iter()
                .map(|&vr| {
                    let v = lookup(&inst.vars, &inst.log, F, vr)?;
                    if v.causality != Causality::Output || !matches!(v.ty, VarType::Real { .. }) {
                        return Err(refuse(v, vr, "an unknown", "unknowns must be Real outputs"));
                    }
                    Ok((v.id, v.name, &v.depends_on))
                })
                .collect::<Result<Vec<_>, _>>()?;
            let k_ids = knowns
                .iter()
                .map(|&vr| {
                    let v = lookup(&inst.vars, &inst.log, F, vr)?;
                    match (v.causality, v.ty) {
                        (Causality::Input, VarType::Real { .. }) => {
                            Ok((v.id, v.name, Known::Input))
                        }
                        (Causality::Parameter, VarType::Real { min, max, .. })
                            if initializing && effective_initial(v) == Some(Initial::Exact) =>
                        {
                            Ok((v.id, v.name, Known::Parameter { min, max }))
                        }
                        _ if initializing => {
                            Err(refuse(v, vr, "a known", "knowns must be Real inputs or Real parameters"))
                        }
                        _ => Err(refuse(
                            v,
                            vr,
                            "a known",
                            "knowns must be Real inputs (Real parameters only in initialization mode)",
                        )),
                    }
                })
                .collect::<Result<Vec<_>, _>>()?;
            // In initialization mode the initial values are computed first —
            // on a copy, committed only when every partial derivative can be
            // taken, so that a refused call changes nothing.
            let pending = !u_ids.is_empty() && initializing && inst.layer.dirty;
            let mut initialized = None;
            if pending {
                let mut trial = inst.model.clone();
                if let Err(ModelError(msg)) = trial.initialize() {
                    inst.log.error(&format!(
                        "{F}: the initial values cannot be computed: {msg}"
                    ));
                    return Err(fmi2Error);
                }
                initialized = Some(trial);
            }
            let model = initialized.as_ref().unwrap_or(&inst.model);
            let mut result = vec![0.0; u_ids.len()];
            for (&(k, k_name, known), &dk) in k_ids.iter().zip(dv_k) {
                let Known::Parameter { min, max } = known else {
                    for (r, &(u, u_name, _)) in result.iter_mut().zip(&u_ids) {
                        match model.partial_derivative(u, k) {
                            Ok(p) => *r += p * dk,
                            Err(ModelError(msg)) => {
                                inst.log
                                    .error(&format!("{F}: d({u_name})/d({k_name}): {msg}"));
                                return Err(fmi2Error);
                            }
                        }
                    }
                    continue;
                };
                // A parameter: differences of the initial values, for the
                // unknowns whose initial value depends on it.
                let dependent: Vec<usize> = (0..u_ids.len())
                    .filter(|&i| u_ids[i].2.contains(&k_name))
                    .collect();
                if dependent.is_empty() {
                    continue;
                }
                let of: Vec<M::Var> = dependent.iter().map(|&i| u_ids[i].0).collect();
                match initial_parameter_column(model, k, min, max, &of) {
                    Ok(column) => {
                        for (&i, p) in dependent.iter().zip(column) {
                            result[i] += p * dk;
                        }
                    }
                    Err(msg) => {
                        let names: Vec<&str> = dependent.iter().map(|&i| u_ids[i].1).collect();
                        inst.log.error(&format!(
                            "{F}: d({})/d({k_name}) in initialization mode: {msg}",
                            names.join(", ")
                        ));
                        return Err(fmi2Error);
                    }
                }
            }
            if let Some(trial) = initialized {
                inst.model = trial;
                inst.layer.dirty = false;
                inst.log.debug(LogCategory::Events, || {
                    format!("{F}: initial values computed")
                });
            }
            dv_u.copy_from_slice(&result);
            Ok(fmi2OK)
        })
    }
}

// ---------------------------------------------------------------------------
// Co-Simulation (FMI 2.0 spec, sections 4.2.1 - 4.2.3)
// ---------------------------------------------------------------------------

/// `fmi2SetRealInputDerivatives` (FMI 2.0 spec, section 4.2.1): only Real
/// inputs, `order` in `1..=ModelInfo::max_input_derivative_order`, forwarded
/// to [`Model::set_real_input_derivative`]. All-or-nothing like
/// [`set_real`].
///
/// # Safety
/// `c` a live instance; `vr`, `order`, `value` `nvr` elements each.
pub unsafe fn set_real_input_derivatives<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2SetRealInputDerivatives";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::SET_REAL_INPUT_DERIVATIVES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let orders = in_slice(&inst.log, F, "order", order, nvr)?;
            let vals = in_slice(&inst.log, F, "value", value, nvr)?;
            let max = inst.info.max_input_derivative_order;
            let mut targets = Vec::with_capacity(nvr);
            for ((&vr, &ord), &val) in vrs.iter().zip(orders).zip(vals) {
                let v = lookup(&inst.vars, &inst.log, F, vr)?;
                if v.causality != Causality::Input || !matches!(v.ty, VarType::Real { .. }) {
                    inst.log.error(&format!(
                        "{F}: '{}' (value reference {vr}) is not a Real input",
                        v.name
                    ));
                    return Err(fmi2Error);
                }
                if ord < 1 || ord > max {
                    inst.log.error(&format!(
                        "{F}: order {ord} for '{}' is not supported (this FMU accepts input derivatives of order 1 to {max}; canInterpolateInputs = {})",
                        v.name,
                        max >= 1
                    ));
                    return Err(fmi2Error);
                }
                targets.push((v.id, v.name, ord, val));
            }
            let backup = (targets.len() > 1).then(|| inst.model.clone());
            for &(id, name, ord, val) in &targets {
                if let Err(ModelError(msg)) = inst.model.set_real_input_derivative(id, ord, val) {
                    if let Some(b) = backup {
                        inst.model = b;
                    }
                    inst.log.error(&format!(
                        "{F}: cannot set derivative of order {ord} of '{name}' = {val:?}: {msg}"
                    ));
                    return Err(fmi2Error);
                }
            }
            inst.log.debug(LogCategory::All, || {
                let items: Vec<String> = targets
                    .iter()
                    .map(|&(_, name, ord, val)| format!("d^{ord} {name} = {val:?}"))
                    .collect();
                format!("{F}: {}", items.join(", "))
            });
            Ok(fmi2OK)
        })
    }
}

/// `fmi2GetRealOutputDerivatives` (FMI 2.0 spec, section 4.2.1). The FMUs
/// declare `maxOutputDerivativeOrder = 0`: after the state and pointer
/// checks, any request (`nvr > 0`) is an error saying output derivatives are
/// not provided; `nvr == 0` requests nothing and returns `fmi2OK`.
///
/// # Safety
/// `c` a live instance; `vr`, `order`, `value` `nvr` elements each.
pub unsafe fn get_real_output_derivatives<M: Model>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: usize,
    order: *const fmi2Integer,
    value: *mut fmi2Real,
) -> fmi2Status {
    const F: &str = "fmi2GetRealOutputDerivatives";
    // SAFETY: forwarded contract.
    unsafe {
        call::<M>(c, F, state::GET_REAL_OUTPUT_DERIVATIVES, |inst| {
            let vrs = in_slice(&inst.log, F, "vr", vr, nvr)?;
            let orders = in_slice(&inst.log, F, "order", order, nvr)?;
            out_slice(&inst.log, F, "value", value, nvr)?;
            if let (Some(&vr), Some(&ord)) = (vrs.first(), orders.first()) {
                let v = lookup(&inst.vars, &inst.log, F, vr)?;
                inst.log.error(&format!(
                    "{F}: output derivatives are not provided (maxOutputDerivativeOrder = 0); requested order {ord} of '{}'",
                    v.name
                ));
                return Err(fmi2Error);
            }
            Ok(fmi2OK)
        })
    }
}
