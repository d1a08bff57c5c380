//! `modelDescription.xml` (FMI 2.0 spec, section 2.2), the GUID that ties it
//! to the binary, a table check, and the FMU's `documentation/index.html`
//! (FMI 2.0 spec, section 2.3), all generated from one variable table.
//!
//! `<ModelStructure>` (FMI 2.0 spec, section 2.2.8), as derived from
//! [`ScalarVariable::depends_on`]:
//! - `<Outputs>`: every output, `dependencies` = its `depends_on` entries
//!   that are inputs (the knowns at a communication point are inputs, states
//!   and the independent variable; no states are exposed), possibly empty
//!   (= no direct feedthrough).
//! - `<InitialUnknowns>`: per the FMI 2.0 schema, exactly the outputs with
//!   `initial` = `approx` or `calculated`, and every `calculatedParameter`
//!   (no state derivatives are exposed), in index order; `dependencies` =
//!   the `depends_on` entries that are knowns of initialization mode, i.e.
//!   inputs and variables with `initial = "exact"` (independent parameters).
//!
//! `dependenciesKind` is omitted (= no particular structure); indices are
//! 1-based positions in `<ModelVariables>`, sorted ascending.

use std::fmt::Write as _;
use std::io;

use quick_xml::events::{BytesDecl, Event};
use quick_xml::Writer;

use super::bytes::{fnv1a64, FNV64_OFFSET};
use super::instance::{LOG_CATEGORIES, STATE_FORMAT_VERSION};
use super::model::{Causality, Initial, Model, ModelInfo, ScalarVariable, VarType};
use super::rules::{
    causality_name, combination_valid, effective_initial, initial_name, type_name, variability_name,
};

/// `generationTool` attribute.
pub const GENERATION_TOOL: &str = concat!("hill-muscle fmu_build ", env!("CARGO_PKG_VERSION"));

/// The `<CoSimulation>` capability flags after `modelIdentifier`
/// (FMI 2.0 spec, section 4.3.1), in the order they are written.
pub fn capability_flags(info: &ModelInfo) -> Vec<(&'static str, String)> {
    let b = |v: bool| v.to_string();
    vec![
        ("canHandleVariableCommunicationStepSize", b(true)),
        (
            "canInterpolateInputs",
            b(info.max_input_derivative_order >= 1),
        ),
        ("maxOutputDerivativeOrder", "0".to_string()),
        ("canGetAndSetFMUstate", b(true)),
        ("canSerializeFMUstate", b(true)),
        ("providesDirectionalDerivative", b(true)),
        ("canNotUseMemoryManagementFunctions", b(true)),
        ("canRunAsynchronuously", b(false)),
        ("canBeInstantiatedOnlyOncePerProcess", b(false)),
        ("needsExecutionTool", b(false)),
    ]
}

/// A Real as an `xs:double` that parses back to the same `f64` (shortest
/// round-trip form, e.g. `1e-9`, `0.5`, `INF`).
pub fn format_real(x: f64) -> String {
    if x.is_nan() {
        "NaN".to_string()
    } else if x == f64::INFINITY {
        "INF".to_string()
    } else if x == f64::NEG_INFINITY {
        "-INF".to_string()
    } else {
        format!("{x:?}")
    }
}

fn opt<T: ToString>(v: Option<T>) -> String {
    v.map_or_else(|| "-".to_string(), |v| v.to_string())
}

/// The text the GUID is a hash of: every fact of the interface an importer
/// relies on (variables with causality, variability, initial, type, unit,
/// start, min, max and dependencies; units; capability flags; model
/// identifier and version), the crate version and the FMU state format
/// version.
pub fn canonical_interface_text<V>(info: &ModelInfo, vars: &[ScalarVariable<V>]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "fmiVersion 2.0");
    let _ = writeln!(s, "crate {}", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(s, "stateFormat {STATE_FORMAT_VERSION}");
    let _ = writeln!(s, "modelIdentifier {}", info.model_identifier);
    let _ = writeln!(s, "version {}", info.version);
    for (k, v) in capability_flags(info) {
        let _ = writeln!(s, "cap {k}={v}");
    }
    let _ = writeln!(
        s,
        "maxInputDerivativeOrder {}",
        info.max_input_derivative_order
    );
    let _ = writeln!(s, "directFeedthrough {}", info.direct_feedthrough);
    for u in &info.units {
        let _ = writeln!(s, "unit {} kg={} m={} s={}", u.name, u.kg, u.m, u.s);
    }
    for (i, v) in vars.iter().enumerate() {
        let ty = match &v.ty {
            VarType::Real {
                unit,
                start,
                min,
                max,
            } => format!(
                "Real unit={} start={} min={} max={}",
                unit.unwrap_or("-"),
                opt(start.map(format_real)),
                opt(min.map(format_real)),
                opt(max.map(format_real))
            ),
            VarType::Integer { start, min, max } => format!(
                "Integer start={} min={} max={}",
                opt(*start),
                opt(*min),
                opt(*max)
            ),
            VarType::Boolean { start } => format!("Boolean start={}", opt(*start)),
        };
        let _ = writeln!(
            s,
            "var {i} {:?} {} {} {} {ty} deps={:?}",
            v.name,
            causality_name(v.causality),
            variability_name(v.variability),
            v.initial.map_or("-", initial_name),
            v.depends_on
        );
    }
    s
}

/// Final mix of a 64-bit hash (splitmix64 finalizer).
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Deterministic GUID of an interface: two 64-bit FNV-1a hashes (different
/// offset bases) of [`canonical_interface_text`], formatted as a UUID
/// (version nibble 8 = "custom", RFC 9562) in braces, e.g.
/// `{0f1e2d3c-4b5a-8968-8776-655443322110}`.
pub fn guid_for<V>(info: &ModelInfo, vars: &[ScalarVariable<V>]) -> String {
    let text = canonical_interface_text(info, vars);
    let h1 = mix(fnv1a64(FNV64_OFFSET, text.as_bytes()));
    let h2 = mix(fnv1a64(
        FNV64_OFFSET ^ 0x9e37_79b9_7f4a_7c15,
        text.as_bytes(),
    ));
    let mut b = [0u8; 16];
    b[..8].copy_from_slice(&h1.to_be_bytes());
    b[8..].copy_from_slice(&h2.to_be_bytes());
    b[6] = (b[6] & 0x0f) | 0x80;
    b[8] = (b[8] & 0x3f) | 0x80;
    let hex: String = b.iter().map(|x| format!("{x:02x}")).collect();
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

/// The GUID of model `M` (the value `fmi2Instantiate` checks `fmuGUID`
/// against and the `guid` attribute of its `modelDescription.xml`).
pub fn guid<M: Model>() -> String {
    guid_for(&M::info(), &M::variables())
}

fn index_of<V>(vars: &[ScalarVariable<V>], name: &str) -> Option<usize> {
    vars.iter().position(|v| v.name == name)
}

/// 1-based `<ModelVariables>` indices of the `depends_on` entries of `v`
/// that satisfy `keep`, sorted, without duplicates.
///
/// # Panics
/// If a `depends_on` entry names no variable of the table (a programming
/// error that [`validate`] reports).
fn dependency_indices<V>(
    vars: &[ScalarVariable<V>],
    v: &ScalarVariable<V>,
    keep: impl Fn(&ScalarVariable<V>) -> bool,
) -> Vec<usize> {
    let mut idx: Vec<usize> = v
        .depends_on
        .iter()
        .map(|d| {
            index_of(vars, d).unwrap_or_else(|| {
                panic!(
                    "variable '{}' depends on '{d}', which is not in the variable table",
                    v.name
                )
            })
        })
        .filter(|&i| keep(&vars[i]))
        .map(|i| i + 1)
        .collect();
    idx.sort_unstable();
    idx.dedup();
    idx
}

/// `<Outputs>` entries: (1-based index, dependencies). Without direct
/// feedthrough ([`ModelInfo::direct_feedthrough`]) no output depends on an
/// input at a communication point, so every list is empty.
pub fn output_dependencies<V>(
    info: &ModelInfo,
    vars: &[ScalarVariable<V>],
) -> Vec<(usize, Vec<usize>)> {
    vars.iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(i, v)| {
            let deps = if info.direct_feedthrough {
                dependency_indices(vars, v, |d| d.causality == Causality::Input)
            } else {
                Vec::new()
            };
            (i + 1, deps)
        })
        .collect()
}

/// `<InitialUnknowns>` entries: (1-based index, dependencies).
pub fn initial_unknown_dependencies<V>(vars: &[ScalarVariable<V>]) -> Vec<(usize, Vec<usize>)> {
    vars.iter()
        .enumerate()
        .filter(|(_, v)| {
            (v.causality == Causality::Output
                && matches!(
                    effective_initial(v),
                    Some(Initial::Approx | Initial::Calculated)
                ))
                || v.causality == Causality::CalculatedParameter
        })
        .map(|(i, v)| {
            (
                i + 1,
                dependency_indices(vars, v, |d| {
                    d.causality == Causality::Input || effective_initial(d) == Some(Initial::Exact)
                }),
            )
        })
        .collect()
}

fn join(idx: &[usize]) -> String {
    idx.iter()
        .map(|i| i.to_string())
        .collect::<Vec<_>>()
        .join(" ")
}

/// `modelDescription.xml` of model `M` (2-space indent, UTF-8).
///
/// # Panics
/// On a `depends_on` entry that names no variable (check with
/// [`validate_table`]); this runs at build time, not across the C ABI.
pub fn model_description<M: Model>() -> String {
    model_description_for(&M::info(), &M::variables())
}

/// [`model_description`] for an explicit info and table.
pub fn model_description_for<V>(info: &ModelInfo, vars: &[ScalarVariable<V>]) -> String {
    let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
    write_description(&mut w, info, vars).expect("writing XML to a Vec cannot fail");
    let mut s = String::from_utf8(w.into_inner()).expect("the XML writer emits UTF-8");
    s.push('\n');
    s
}

fn write_description<V>(
    w: &mut Writer<Vec<u8>>,
    info: &ModelInfo,
    vars: &[ScalarVariable<V>],
) -> io::Result<()> {
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    let guid = guid_for(info, vars);
    let mut root: Vec<(&str, String)> = vec![
        ("fmiVersion", "2.0".into()),
        ("modelName", info.model_identifier.into()),
        ("guid", guid),
    ];
    if !info.description.is_empty() {
        root.push(("description", info.description.into()));
    }
    if !info.version.is_empty() {
        root.push(("version", info.version.into()));
    }
    root.push(("generationTool", GENERATION_TOOL.into()));
    root.push(("variableNamingConvention", "flat".into()));
    root.push(("numberOfEventIndicators", "0".into()));
    w.create_element("fmiModelDescription")
        .with_attributes(root.iter().map(|(k, v)| (*k, v.as_str())))
        .write_inner_content(|w| {
            let mut cs: Vec<(&str, String)> =
                vec![("modelIdentifier", info.model_identifier.into())];
            cs.extend(capability_flags(info));
            w.create_element("CoSimulation")
                .with_attributes(cs.iter().map(|(k, v)| (*k, v.as_str())))
                .write_empty()?;

            if !info.units.is_empty() {
                w.create_element("UnitDefinitions")
                    .write_inner_content(|w| {
                        for u in &info.units {
                            w.create_element("Unit")
                                .with_attribute(("name", u.name))
                                .write_inner_content(|w| {
                                    let exps: Vec<(&str, String)> =
                                        [("kg", u.kg), ("m", u.m), ("s", u.s)]
                                            .into_iter()
                                            .filter(|(_, e)| *e != 0)
                                            .map(|(k, e)| (k, e.to_string()))
                                            .collect();
                                    w.create_element("BaseUnit")
                                        .with_attributes(exps.iter().map(|(k, v)| (*k, v.as_str())))
                                        .write_empty()?;
                                    Ok(())
                                })?;
                        }
                        Ok(())
                    })?;
            }

            w.create_element("LogCategories").write_inner_content(|w| {
                for (name, description) in LOG_CATEGORIES {
                    w.create_element("Category")
                        .with_attribute(("name", name))
                        .with_attribute(("description", description))
                        .write_empty()?;
                }
                Ok(())
            })?;

            let (start, stop, step) = info.default_experiment;
            let (start, stop, step) = (format_real(start), format_real(stop), format_real(step));
            w.create_element("DefaultExperiment")
                .with_attribute(("startTime", start.as_str()))
                .with_attribute(("stopTime", stop.as_str()))
                .with_attribute(("stepSize", step.as_str()))
                .write_empty()?;

            w.create_element("ModelVariables")
                .write_inner_content(|w| {
                    for (vr, v) in vars.iter().enumerate() {
                        write_variable(w, vr, v)?;
                    }
                    Ok(())
                })?;

            w.create_element("ModelStructure")
                .write_inner_content(|w| {
                    for (tag, list) in [
                        ("Outputs", output_dependencies(info, vars)),
                        ("InitialUnknowns", initial_unknown_dependencies(vars)),
                    ] {
                        if list.is_empty() {
                            continue;
                        }
                        w.create_element(tag).write_inner_content(|w| {
                            for (index, deps) in &list {
                                let index = index.to_string();
                                let deps = join(deps);
                                w.create_element("Unknown")
                                    .with_attribute(("index", index.as_str()))
                                    .with_attribute(("dependencies", deps.as_str()))
                                    .write_empty()?;
                            }
                            Ok(())
                        })?;
                    }
                    Ok(())
                })?;
            Ok(())
        })?;
    Ok(())
}

fn write_variable<V>(w: &mut Writer<Vec<u8>>, vr: usize, v: &ScalarVariable<V>) -> io::Result<()> {
    let mut attrs: Vec<(&str, String)> =
        vec![("name", v.name.into()), ("valueReference", vr.to_string())];
    if !v.description.is_empty() {
        attrs.push(("description", v.description.into()));
    }
    attrs.push(("causality", causality_name(v.causality).into()));
    attrs.push(("variability", variability_name(v.variability).into()));
    if let Some(i) = v.initial {
        attrs.push(("initial", initial_name(i).into()));
    }
    let (tag, ty_attrs): (&str, Vec<(&str, String)>) = match &v.ty {
        VarType::Real {
            unit,
            start,
            min,
            max,
        } => {
            let mut a = Vec::new();
            if let Some(u) = unit {
                a.push(("unit", u.to_string()));
            }
            if let Some(x) = start {
                a.push(("start", format_real(*x)));
            }
            if let Some(x) = min {
                a.push(("min", format_real(*x)));
            }
            if let Some(x) = max {
                a.push(("max", format_real(*x)));
            }
            ("Real", a)
        }
        VarType::Integer { start, min, max } => {
            let mut a = Vec::new();
            if let Some(x) = start {
                a.push(("start", x.to_string()));
            }
            if let Some(x) = min {
                a.push(("min", x.to_string()));
            }
            if let Some(x) = max {
                a.push(("max", x.to_string()));
            }
            ("Integer", a)
        }
        VarType::Boolean { start } => {
            let a = start
                .map(|b| ("start", b.to_string()))
                .into_iter()
                .collect();
            ("Boolean", a)
        }
    };
    w.create_element("ScalarVariable")
        .with_attributes(attrs.iter().map(|(k, v)| (*k, v.as_str())))
        .write_inner_content(|w| {
            w.create_element(tag)
                .with_attributes(ty_attrs.iter().map(|(k, v)| (*k, v.as_str())))
                .write_empty()?;
            Ok(())
        })?;
    Ok(())
}

/// Checks the table and info of model `M` against the FMI 2.0 rules this
/// layer relies on; returns every problem found.
pub fn validate_table<M: Model>() -> Result<(), Vec<String>> {
    validate(&M::info(), &M::variables())
}

/// [`validate_table`] for an explicit info and table. Checks: model
/// identifier is a C identifier; unique unit and variable names; valid
/// causality/variability/initial combinations (FMI 2.0 section 2.2.7); start
/// value present exactly when required (initial exact/approx or input) and
/// absent for calculated/independent; `min <= start <= max`; no NaN; units
/// declared; continuous variability only for Reals; `depends_on` names exist, only on outputs and calculated
/// parameters, and name inputs or variables with `initial = "exact"`;
/// default experiment `start < stop`, `step > 0`; at most one independent
/// variable.
pub fn validate<V>(info: &ModelInfo, vars: &[ScalarVariable<V>]) -> Result<(), Vec<String>> {
    let mut errs = Vec::new();
    let id = info.model_identifier;
    let is_c_ident = id
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !is_c_ident {
        errs.push(format!("modelIdentifier '{id}' is not a C identifier"));
    }
    for (i, u) in info.units.iter().enumerate() {
        if u.name.is_empty() {
            errs.push(format!("unit {i} has an empty name"));
        }
        if info.units[..i].iter().any(|o| o.name == u.name) {
            errs.push(format!("unit '{}' is declared twice", u.name));
        }
    }
    let (start, stop, step) = info.default_experiment;
    if !(start.is_finite() && stop.is_finite() && start < stop) {
        errs.push(format!(
            "DefaultExperiment: startTime {start} must be < stopTime {stop}"
        ));
    }
    if !(step.is_finite() && step > 0.0) {
        errs.push(format!("DefaultExperiment: stepSize {step} must be > 0"));
    }
    if info.max_input_derivative_order < 0 {
        errs.push("max_input_derivative_order must be >= 0".into());
    }
    if vars.len() > u32::MAX as usize {
        errs.push("too many variables for 32-bit value references".into());
    }
    let independents = vars
        .iter()
        .filter(|v| v.causality == Causality::Independent)
        .count();
    if independents > 1 {
        errs.push(format!(
            "{independents} independent variables (at most one allowed)"
        ));
    }
    for (i, v) in vars.iter().enumerate() {
        let name = v.name;
        let mut err = |m: String| errs.push(format!("variable {i} '{name}': {m}"));
        if name.trim().is_empty() {
            err("empty name".into());
        }
        if vars[..i].iter().any(|o| o.name == name) {
            err("duplicate name".into());
        }
        if let Err(m) = combination_valid(v) {
            err(m);
        }
        // FMI 2.0 section 2.2.7: only Real variables may be continuous.
        if v.variability == super::model::Variability::Continuous
            && !matches!(v.ty, VarType::Real { .. })
        {
            err("only Real variables may have variability continuous".into());
        }
        let initial = effective_initial(v);
        let start_required = v.causality == Causality::Input
            || matches!(initial, Some(Initial::Exact | Initial::Approx));
        let start_forbidden = v.causality == Causality::Independent
            || (v.causality != Causality::Input && initial == Some(Initial::Calculated));
        let has_start = match &v.ty {
            VarType::Real { start, .. } => start.is_some(),
            VarType::Integer { start, .. } => start.is_some(),
            VarType::Boolean { start } => start.is_some(),
        };
        if start_required && !has_start {
            err("a start value is required (initial exact/approx or input)".into());
        }
        if start_forbidden && has_start {
            err("a start value is not allowed (initial calculated or independent)".into());
        }
        match &v.ty {
            VarType::Real {
                unit,
                start,
                min,
                max,
            } => {
                for (what, x) in [("start", start), ("min", min), ("max", max)] {
                    if x.is_some_and(f64::is_nan) {
                        err(format!("{what} is NaN"));
                    }
                }
                if let (Some(lo), Some(hi)) = (min, max) {
                    if lo > hi {
                        err(format!("min {lo} > max {hi}"));
                    }
                }
                if let Some(s) = start {
                    if min.is_some_and(|lo| *s < lo) || max.is_some_and(|hi| *s > hi) {
                        err(format!("start {s} outside [min, max]"));
                    }
                }
                if let Some(u) = unit {
                    if !info.units.iter().any(|d| d.name == *u) {
                        err(format!("unit '{u}' is not declared in ModelInfo::units"));
                    }
                }
            }
            VarType::Integer { start, min, max } => {
                if let (Some(lo), Some(hi)) = (min, max) {
                    if lo > hi {
                        err(format!("min {lo} > max {hi}"));
                    }
                }
                if let Some(s) = start {
                    if min.is_some_and(|lo| *s < lo) || max.is_some_and(|hi| *s > hi) {
                        err(format!("start {s} outside [min, max]"));
                    }
                }
            }
            VarType::Boolean { .. } => {}
        }
        if !v.depends_on.is_empty()
            && !matches!(
                v.causality,
                Causality::Output | Causality::CalculatedParameter
            )
        {
            err("depends_on is only meaningful for outputs and calculated parameters".into());
        }
        for d in &v.depends_on {
            match index_of(vars, d) {
                None => err(format!("depends_on '{d}' is not a variable")),
                Some(j) if j == i => err("depends on itself".into()),
                Some(j) => {
                    let dv = &vars[j];
                    let known = dv.causality == Causality::Input
                        || effective_initial(dv) == Some(Initial::Exact);
                    if !known {
                        err(format!(
                            "depends_on '{d}' is neither an input nor a variable with initial = exact"
                        ));
                    }
                }
            }
        }
    }
    if errs.is_empty() {
        Ok(())
    } else {
        Err(errs)
    }
}

fn html_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `documentation/index.html` of the FMU (FMI 2.0 spec, section 2.3): model
/// description, capabilities, units, default experiment, the variable table
/// (name, causality, type, unit, start, range, description) and the given
/// description of the law (inserted as HTML, unescaped).
pub fn documentation_html<M: Model>(law_description_html: &str) -> String {
    documentation_html_for(&M::info(), &M::variables(), law_description_html)
}

/// [`documentation_html`] for an explicit info and table.
pub fn documentation_html_for<V>(
    info: &ModelInfo,
    vars: &[ScalarVariable<V>],
    law_description_html: &str,
) -> String {
    let e = html_escape;
    let mut h = String::new();
    let id = e(info.model_identifier);
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{id}</title>"
    );
    h.push_str(
        "<style>body{font-family:sans-serif;max-width:70em;margin:auto;padding:1em}\
         table{border-collapse:collapse}td,th{border:1px solid #999;padding:0.2em 0.5em;text-align:left}\
         th{background:#eee}code{font-size:95%}</style>\n</head>\n<body>\n",
    );
    let _ = writeln!(h, "<h1>{id}</h1>");
    let _ = writeln!(h, "<p>{}</p>", e(info.description));
    let _ = writeln!(
        h,
        "<p>FMI 2.0 Co-Simulation FMU, model version {}, GUID <code>{}</code>, generated by {}.</p>",
        e(info.version),
        e(&guid_for(info, vars)),
        e(GENERATION_TOOL)
    );
    h.push_str("<h2>Capabilities</h2>\n<ul>\n");
    for (k, v) in capability_flags(info) {
        let _ = writeln!(h, "<li><code>{k} = {v}</code></li>");
    }
    h.push_str("</ul>\n");
    let (start, stop, step) = info.default_experiment;
    let _ = writeln!(
        h,
        "<h2>Default experiment</h2>\n<p>start {} s, stop {} s, communication step {} s</p>",
        format_real(start),
        format_real(stop),
        format_real(step)
    );
    if !info.units.is_empty() {
        h.push_str(
            "<h2>Units</h2>\n<table>\n<tr><th>unit</th><th>kg</th><th>m</th><th>s</th></tr>\n",
        );
        for u in &info.units {
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                e(u.name),
                u.kg,
                u.m,
                u.s
            );
        }
        h.push_str("</table>\n");
    }
    h.push_str(
        "<h2>Variables</h2>\n<table>\n<tr><th>value reference</th><th>name</th><th>causality</th>\
         <th>variability</th><th>type</th><th>unit</th><th>start</th><th>range</th><th>description</th></tr>\n",
    );
    for (vr, v) in vars.iter().enumerate() {
        let (unit, start, range) = match &v.ty {
            VarType::Real {
                unit,
                start,
                min,
                max,
            } => (
                unit.unwrap_or("").to_string(),
                start.map(format_real).unwrap_or_default(),
                range_text(min.map(format_real), max.map(format_real)),
            ),
            VarType::Integer { start, min, max } => (
                String::new(),
                start.map(|s| s.to_string()).unwrap_or_default(),
                range_text(min.map(|x| x.to_string()), max.map(|x| x.to_string())),
            ),
            VarType::Boolean { start } => (
                String::new(),
                start.map(|s| s.to_string()).unwrap_or_default(),
                String::new(),
            ),
        };
        let _ = writeln!(
            h,
            "<tr><td>{vr}</td><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            e(v.name),
            causality_name(v.causality),
            variability_name(v.variability),
            type_name(&v.ty),
            e(&unit),
            e(&start),
            e(&range),
            e(v.description)
        );
    }
    h.push_str("</table>\n");
    h.push_str("<h2>Model</h2>\n");
    h.push_str(law_description_html);
    h.push_str("\n</body>\n</html>\n");
    h
}

fn range_text(min: Option<String>, max: Option<String>) -> String {
    match (min, max) {
        (None, None) => String::new(),
        (lo, hi) => format!(
            "[{}, {}]",
            lo.unwrap_or_else(|| "-inf".into()),
            hi.unwrap_or_else(|| "inf".into())
        ),
    }
}
