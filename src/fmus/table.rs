//! A model's variables as one table. A [`Row`] says everything
//! modelDescription says of a variable (name, description, causality,
//! variability, type, unit, start, range, dependencies) and how a value set
//! on it is checked ([`Check`]); [`variables!`] turns a model's list of rows,
//! each with where the value lives on the model, into its `Var` enum,
//! `all_variables()` and the get/set dispatch ([`model_access!`]).
//!
//! The rows both muscle models have are declared here once: the law's
//! parameters ([`LawParameters`], from [`PARAMETERS`]), `L0`, `area`, the
//! activation and substep options, the inputs `activation` and `length`,
//! and the names and units of the common outputs.
//!
//! Invariant: a value set on a variable is admitted by its row's check
//! against the row's declared range before the model sees it, with the
//! messages of [`Check`]; a row without a setter refuses every set.

use crate::fmi2::{
    Causality, Initial, ModelError, ScalarVariable, SetOutcome, VarType, Variability,
};
use crate::law::params::{
    out_of_range, Bound, ParamInfo, Range, AREA_RANGE, L0_RANGE, LENGTH_RANGE,
};
use crate::law::{ParamId, PARAMETERS};
pub use crate::scene::Value;

use super::common::{SUBSTEP_RTOL, SUBSTEP_TOLERANCE_RANGE};

/// How a value set on a variable is checked against its row's declared
/// [min, max], and the message a refused value gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Check {
    /// Any value (Booleans; read-only outputs are never set).
    None,
    /// Finite and in [min, max], else "`name` = `v` is out of range: must
    /// be finite and in [min, max]".
    Finite,
    /// As [`Check::Finite`], the message naming "parameter `name`" (the
    /// law's own message, [`crate::law::ParamError`]).
    LawParameter,
    /// In [min, max] (NaN refused), else "`name` = `v` is out of range:
    /// must be in [min, max]".
    Closed,
    /// NaN refused as [`Check::Closed`]; any other value clamped into
    /// [min, max] with a warning logged once per instance.
    Clamp,
}

/// One variable of a model's table: everything but the model's handle for
/// it and where its value lives (those are the model's, [`variables!`]).
#[derive(Clone, Copy, Debug)]
pub struct Row<V> {
    pub name: &'static str,
    pub description: &'static str,
    pub causality: Causality,
    pub variability: Variability,
    pub initial: Option<Initial>,
    pub ty: VarType,
    pub check: Check,
    /// Outputs: the variables this one depends on (FMI 2.0 spec, section
    /// 2.2.8), in the order modelDescription lists them.
    pub depends_on: fn() -> Vec<V>,
}

/// No dependencies.
pub fn none<V>() -> Vec<V> {
    Vec::new()
}

/// A Real type with a unit, start and range (unbounded where `None`).
pub const fn real(unit: &'static str, start: Option<f64>, range: Option<Range>) -> VarType {
    let (min, max) = match range {
        Some(r) => (Some(r.min), Some(r.max)),
        None => (None, None),
    };
    VarType::Real {
        unit: Some(unit),
        start,
        min,
        max,
    }
}

/// An Integer type with a start and range.
pub const fn integer(start: i32, (min, max): (i32, i32)) -> VarType {
    VarType::Integer {
        start: Some(start),
        min: Some(min),
        max: Some(max),
    }
}

/// A Boolean type with a start.
pub const fn boolean(start: bool) -> VarType {
    VarType::Boolean { start: Some(start) }
}

/// A fixed parameter of type `ty`, values set checked by `check`.
pub const fn parameter<V>(
    name: &'static str,
    description: &'static str,
    ty: VarType,
    check: Check,
) -> Row<V> {
    Row {
        name,
        description,
        causality: Causality::Parameter,
        variability: Variability::Fixed,
        initial: None,
        ty,
        check,
        depends_on: none,
    }
}

/// A continuous Real input.
pub const fn input<V>(
    name: &'static str,
    description: &'static str,
    ty: VarType,
    check: Check,
) -> Row<V> {
    Row {
        causality: Causality::Input,
        variability: Variability::Continuous,
        ..parameter(name, description, ty, check)
    }
}

/// A continuous Real output in `unit`, calculated at initialization.
pub const fn output<V>(
    name: &'static str,
    description: &'static str,
    unit: &'static str,
    depends_on: fn() -> Vec<V>,
) -> Row<V> {
    Row {
        causality: Causality::Output,
        variability: Variability::Continuous,
        initial: Some(Initial::Calculated),
        depends_on,
        ..parameter(name, description, real(unit, None, None), Check::None)
    }
}

/// The law's parameter `info` (MODEL_NOTES "Parameters"): its name, unit,
/// default and range.
pub const fn law_parameter<V>(info: &ParamInfo) -> Row<V> {
    parameter(
        info.name,
        info.description,
        real(info.unit, Some(info.default), Some(info.range)),
        Check::LawParameter,
    )
}

/// The law's parameters as a family of rows, in [`PARAMETERS`] order: both
/// models' first rows.
pub struct LawParameters;

impl<V> Family<ParamId, V> for LawParameters {
    fn rows(&self) -> Vec<(ParamId, Row<V>)> {
        PARAMETERS
            .iter()
            .map(|info| (info.id, law_parameter(info)))
            .collect()
    }

    /// The row of `id`: [`PARAMETERS`] is in [`ParamId`] order.
    #[inline]
    fn row(&self, id: ParamId) -> Row<V> {
        law_parameter(&PARAMETERS[id as usize])
    }
}

/// The law's parameters of its static (isometric, f_v = 1) stress: the
/// ones the initial equilibrium, and so every state output, depend on.
pub const STATIC_LAW: [ParamId; 9] = [
    ParamId::B,
    ParamId::C,
    ParamId::Alpha,
    ParamId::Beta,
    ParamId::A,
    ParamId::Sigma0,
    ParamId::LambdaOpt,
    ParamId::Dcomp,
    ParamId::K,
];

/// `L0`, the rest length, starting at `start`.
pub const fn l0<V>(description: &'static str, start: f64) -> Row<V> {
    parameter(
        "L0",
        description,
        real("m", Some(start), Some(L0_RANGE)),
        Check::Finite,
    )
}

/// `area`, the reference cross-section, starting at `start`.
pub const fn area<V>(description: &'static str, start: f64) -> Row<V> {
    parameter(
        "area",
        description,
        real("m2", Some(start), Some(AREA_RANGE)),
        Check::Finite,
    )
}

/// `activation_dynamics` (MODEL_NOTES "Activation dynamics").
pub const fn activation_dynamics<V>() -> Row<V> {
    parameter(
        "activation_dynamics",
        "Use first-order activation dynamics da/dt = S (u - a); false: a = u",
        boolean(true),
        Check::None,
    )
}

/// `initial_activation`, the activation level at the start time.
pub const fn initial_activation<V>() -> Row<V> {
    parameter(
        "initial_activation",
        "Activation level at the start time",
        real("1", Some(0.0), Some(Range { min: 0.0, max: 1.0 })),
        Check::Closed,
    )
}

/// `adaptive_substeps`, on at `start`.
pub const fn adaptive_substeps<V>(description: &'static str, start: bool) -> Row<V> {
    parameter(
        "adaptive_substeps",
        description,
        boolean(start),
        Check::None,
    )
}

/// `substep_tolerance`: a fraction of sigma0, [`SUBSTEP_RTOL`] by
/// default, within [`SUBSTEP_TOLERANCE_RANGE`].
pub const fn substep_tolerance<V>(description: &'static str) -> Row<V> {
    parameter(
        "substep_tolerance",
        description,
        real("1", Some(SUBSTEP_RTOL), Some(SUBSTEP_TOLERANCE_RANGE)),
        Check::Finite,
    )
}

/// The input `activation`, the command u (clamped into [0, 1] with a
/// warning).
pub const fn activation<V>() -> Row<V> {
    input(
        "activation",
        "Activation command u in [0, 1] (values outside are clamped with a warning)",
        real("1", Some(0.0), Some(Range { min: 0.0, max: 1.0 })),
        Check::Clamp,
    )
}

/// The input `length`, starting at `start`.
pub const fn length<V>(start: f64) -> Row<V> {
    input(
        "length",
        "Muscle length reached at the end of the step",
        real("m", Some(start), Some(LENGTH_RANGE)),
        Check::Finite,
    )
}

/// The output `force` (N); each model says what it measures.
pub const fn force<V>(description: &'static str, deps: fn() -> Vec<V>) -> Row<V> {
    output("force", description, "N", deps)
}

/// The output `stress` (Pa).
pub const fn stress<V>(deps: fn() -> Vec<V>) -> Row<V> {
    output(
        "stress",
        "Engineering (nominal) stress: force / area",
        "Pa",
        deps,
    )
}

/// The output `cauchy_stress` (Pa).
pub const fn cauchy_stress<V>(description: &'static str, deps: fn() -> Vec<V>) -> Row<V> {
    output("cauchy_stress", description, "Pa", deps)
}

/// The output `activation_level`.
pub const fn activation_level<V>(deps: fn() -> Vec<V>) -> Row<V> {
    output("activation_level", "Activation level a", "1", deps)
}

/// The output `fibre_stretch`.
pub const fn fibre_stretch<V>(description: &'static str, deps: fn() -> Vec<V>) -> Row<V> {
    output("fibre_stretch", description, "1", deps)
}

/// The output `ce_stretch`.
pub const fn ce_stretch<V>(description: &'static str, deps: fn() -> Vec<V>) -> Row<V> {
    output("ce_stretch", description, "1", deps)
}

/// The output `see_stretch`.
pub const fn see_stretch<V>(description: &'static str, deps: fn() -> Vec<V>) -> Row<V> {
    output("see_stretch", description, "1", deps)
}

/// The output `active_stress` (Pa).
pub const fn active_stress<V>(description: &'static str, deps: fn() -> Vec<V>) -> Row<V> {
    output("active_stress", description, "Pa", deps)
}

/// The output `passive_stress` (Pa).
pub const fn passive_stress<V>(description: &'static str, deps: fn() -> Vec<V>) -> Row<V> {
    output("passive_stress", description, "Pa", deps)
}

impl<V> Row<V> {
    /// The declared range of a Real row (unbounded where none is declared).
    fn real_range(&self) -> Range {
        match self.ty {
            VarType::Real { min, max, .. } => Range {
                min: min.unwrap_or(f64::NEG_INFINITY),
                max: max.unwrap_or(f64::INFINITY),
            },
            _ => Range {
                min: f64::NEG_INFINITY,
                max: f64::INFINITY,
            },
        }
    }
}

/// A value set on a variable, admitted by the variable's row.
pub trait Admit: Sized {
    /// The value to store and the outcome to report, or the refusal.
    fn admit<V>(self, row: &Row<V>) -> Result<(Self, SetOutcome), ModelError>;
}

impl Admit for f64 {
    /// The checks inline (the row is a constant where the table knows it);
    /// the messages out of line.
    #[inline]
    fn admit<V>(self, row: &Row<V>) -> Result<(f64, SetOutcome), ModelError> {
        let (x, r) = (self, row.real_range());
        let admitted = match row.check {
            Check::None => true,
            Check::Finite | Check::LawParameter => r.contains(x),
            Check::Closed | Check::Clamp => (r.min..=r.max).contains(&x),
        };
        if admitted {
            Ok((x, SetOutcome::Ok))
        } else {
            refuse_real(x, row.name, row.check, r)
        }
    }
}

/// A value `x` set on variable `name` that its check refuses (or, for
/// [`Check::Clamp`], clamps with a warning), with the messages of [`Check`].
#[cold]
#[inline(never)]
fn refuse_real(
    x: f64,
    name: &str,
    check: Check,
    r: Range,
) -> Result<(f64, SetOutcome), ModelError> {
    let refuse = |prefix: &str, must: String| {
        Err(ModelError(out_of_range(
            format_args!("{prefix}{name}"),
            x,
            must,
        )))
    };
    let closed = || format!("in [{}, {}]", Bound(r.min), Bound(r.max));
    match check {
        Check::LawParameter => refuse("parameter ", r.to_string()),
        Check::Clamp if !x.is_nan() => {
            let clamped = x.clamp(r.min, r.max);
            Ok((
                clamped,
                SetOutcome::Warning {
                    message: format!(
                        "{name} = {x} is outside [{}, {}]; clamped to {clamped} (logged once per instance)",
                        Bound(r.min),
                        Bound(r.max)
                    ),
                    log_once: true,
                },
            ))
        }
        Check::Closed | Check::Clamp => refuse("", closed()),
        Check::Finite | Check::None => refuse("", r.to_string()),
    }
}

impl Admit for i32 {
    #[inline]
    fn admit<V>(self, row: &Row<V>) -> Result<(i32, SetOutcome), ModelError> {
        match (row.check, row.ty) {
            (
                Check::Closed,
                VarType::Integer {
                    min: Some(min),
                    max: Some(max),
                    ..
                },
            ) if !(min..=max).contains(&self) => Err(ModelError(out_of_range(
                row.name,
                self,
                format_args!("in [{min}, {max}]"),
            ))),
            _ => Ok((self, SetOutcome::Ok)),
        }
    }
}

impl Admit for bool {
    #[inline]
    fn admit<V>(self, _row: &Row<V>) -> Result<(bool, SetOutcome), ModelError> {
        Ok((self, SetOutcome::Ok))
    }
}

/// The refusal of `value` set on a variable that does not take it (of
/// another type, or an output).
pub fn refuse(value: Value) -> ModelError {
    ModelError(
        match value {
            Value::Real(_) => "not a Real input or parameter",
            Value::Integer(_) => "not an Integer parameter",
            Value::Boolean(_) => "not a Boolean parameter",
        }
        .into(),
    )
}

/// A family of rows, one per value of `I` (the law's parameters, the
/// outputs): the variant `Variant(id: I)` of a table.
pub trait Family<I, V> {
    /// Every row, in table order.
    fn rows(&self) -> Vec<(I, Row<V>)>;
    /// The row of `id`.
    fn row(&self, id: I) -> Row<V>;
}

/// A family listed as an array of `(id, row)` pairs.
impl<I: Copy + PartialEq + std::fmt::Debug, V: Copy, const N: usize> Family<I, V>
    for [(I, Row<V>); N]
{
    fn rows(&self) -> Vec<(I, Row<V>)> {
        self.iter().map(|&(id, row)| (id, row)).collect()
    }

    /// # Panics
    /// If the array has no row for `id` (a table that declares a variant it
    /// does not list: a programming error).
    fn row(&self, id: I) -> Row<V> {
        self.iter()
            .find(|(i, _)| *i == id)
            .map(|&(_, row)| row)
            .unwrap_or_else(|| panic!("no row for {id:?}"))
    }
}

/// The table's rows as modelDescription's variables: each row with its
/// handle, its dependencies named.
///
/// # Panics
/// If a row depends on a variable the table does not list.
pub fn scalar_variables<V: Copy + PartialEq + std::fmt::Debug>(
    rows: Vec<(V, Row<V>)>,
) -> Vec<ScalarVariable<V>> {
    let name_of = |d: V| {
        rows.iter()
            .find(|(id, _)| *id == d)
            .map(|(_, row)| row.name)
            .unwrap_or_else(|| panic!("a dependency {d:?} is not in the table"))
    };
    rows.iter()
        .map(|&(id, row)| ScalarVariable {
            name: row.name,
            description: row.description,
            causality: row.causality,
            variability: row.variability,
            initial: row.initial,
            ty: row.ty,
            depends_on: (row.depends_on)().into_iter().map(name_of).collect(),
            id,
        })
        .collect()
}

/// A model's variable table: generates the `Var` enum (one variant a row,
/// or a family of rows for `Variant(id: Inner)`), `all_variables()` in row
/// order, and the model's get/set dispatch that [`model_access!`] puts
/// behind [`crate::fmi2::Model`]: `table_get_real`, `table_set_real` (and
/// the same for Integer and Boolean), `table_set_derivative`, and the
/// untyped `table_get` and `table_set`, and `table_apply_scene` (a
/// scene's settings through the setters).
///
/// A row is `Variant = ROW => Kind(ACCESS);`, or `Variant(id: Inner) =
/// FAMILY => Kind(ACCESS);` for a family of rows (a [`Family`]). `Kind` is
/// `Real`, `Integer` or `Boolean`; `ACCESS`, written with the model bound to
/// `m` and the admitted value to `v` (the names given after `as`), is a
/// place (read and written), `get EXPR, set EXPR`, or `get EXPR` (read
/// only); a trailing `, der PLACE` is where an input's derivative goes.
///
/// The typed get/set are one `match` arm per row, as a hand-written match
/// would be: a single row's check runs against the row as a `const`, a
/// family's against its [`Family::row`].
macro_rules! variables {
    (
        $(#[$enum_attr:meta])*
        $vis:vis enum $Var:ident;
        impl [$($gen:tt)*] $Model:ty as ($m:ident, $v:ident) {
            $(
                $(#[$attr:meta])*
                $Variant:ident $(($id:ident: $Inner:ident))? = $row:expr
                    => $Kind:ident $access:tt $(, der $der:expr)?;
            )*
        }
    ) => {
        $(#[$enum_attr])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        $vis enum $Var {
            $( $(#[$attr])* $Variant $(($Inner))?, )*
        }

        /// Every variable the model can expose, in table order (a scene
        /// exposes a subset, [`crate::scene::SceneSpec::variables`]).
        #[allow(clippy::vec_init_then_push)]
        pub fn all_variables() -> Vec<$crate::fmi2::ScalarVariable<$Var>> {
            let mut rows = Vec::new();
            $( $crate::fmus::table::variables!(@rows rows, $Var, $Variant, $row $(, $id)?); )*
            $crate::fmus::table::scalar_variables(rows)
        }

        #[allow(unused_variables, dead_code)]
        impl<$($gen)*> $Model {
            /// The value of `var`, of its row's type.
            fn table_get(&self, var: $Var) -> $crate::fmus::table::Value {
                let $m = self;
                match var {
                    $( $Var::$Variant $(($id))? => $crate::fmus::table::Value::$Kind(
                        $crate::fmus::table::variables!(@get $access)
                    ), )*
                }
            }

            /// Apply the start values and constants of scene `spec` through
            /// the rows' setters (which check them again: the scene was
            /// checked when fmu_build resolved it).
            ///
            /// # Panics
            /// If a setting is refused (a scene type not made by fmu_build).
            fn table_apply_scene(&mut self, spec: &$crate::scene::SceneSpec) {
                $crate::scene::apply_settings(spec, &all_variables(), |var, value| {
                    self.table_set(var, value).map(|_| ()).map_err(|e| e.0)
                })
                .expect("the scene's settings are valid");
            }

            /// Set `var` to `value` once its row admits it.
            fn table_set(
                &mut self,
                var: $Var,
                value: $crate::fmus::table::Value,
            ) -> Result<$crate::fmi2::SetOutcome, $crate::fmi2::ModelError> {
                match value {
                    $crate::fmus::table::Value::Real(x) => self.table_set_real(var, x),
                    $crate::fmus::table::Value::Integer(i) => self.table_set_integer(var, i),
                    $crate::fmus::table::Value::Boolean(b) => self.table_set_boolean(var, b),
                }
            }

            $crate::fmus::table::variables!(@typed $Var, $m, $v, Real, f64,
                table_get_real, table_set_real, f64::NAN;
                $( $Variant $(($id))? = $row => $Kind $access; )*);
            $crate::fmus::table::variables!(@typed $Var, $m, $v, Integer, i32,
                table_get_integer, table_set_integer, 0;
                $( $Variant $(($id))? = $row => $Kind $access; )*);
            $crate::fmus::table::variables!(@typed $Var, $m, $v, Boolean, bool,
                table_get_boolean, table_set_boolean, false;
                $( $Variant $(($id))? = $row => $Kind $access; )*);

            /// Set the derivative of input `var` to `rate`.
            fn table_set_derivative(
                &mut self,
                var: $Var,
                rate: f64,
            ) -> Result<(), $crate::fmi2::ModelError> {
                let $m = self;
                match var {
                    $( $Var::$Variant $(($id))? => {
                        $crate::fmus::table::variables!(@der rate; $($der)?)
                    } )*
                }
            }
        }
    };
    // The get and set of one type: a row of that type is read and written
    // through its access, any other reads as `$other` and refuses a set.
    (@typed $Var:ident, $m:ident, $v:ident, $Ty:ident, $t:ty, $get:ident, $set:ident, $other:expr;
        $( $Variant:ident $(($id:ident))? = $row:expr => $Kind:ident $access:tt; )*) => {
        /// The value of `var` if it is of this type.
        #[inline]
        fn $get(&self, var: $Var) -> $t {
            let $m = self;
            match var {
                $( $Var::$Variant $(($id))? =>
                    $crate::fmus::table::variables!(@get_if $Ty $Kind $access, $other), )*
            }
        }

        /// Set `var`, if it is of this type, to `$v` once its row admits it.
        #[inline]
        fn $set(
            &mut self,
            var: $Var,
            $v: $t,
        ) -> Result<$crate::fmi2::SetOutcome, $crate::fmi2::ModelError> {
            let $m = self;
            match var {
                $( $Var::$Variant $(($id))? => $crate::fmus::table::variables!(
                    @set_if $Ty $Kind $access, $v,
                    $crate::fmus::table::variables!(@row $Var, $row; $($id)?)
                ), )*
            }
        }
    };
    (@get_if Real Real $access:tt, $other:expr) => { $crate::fmus::table::variables!(@get $access) };
    (@get_if Integer Integer $access:tt, $other:expr) => { $crate::fmus::table::variables!(@get $access) };
    (@get_if Boolean Boolean $access:tt, $other:expr) => { $crate::fmus::table::variables!(@get $access) };
    (@get_if $Ty:ident $Kind:ident $access:tt, $other:expr) => { $other };
    (@set_if Real Real $access:tt, $v:ident, $row:expr) => {
        $crate::fmus::table::variables!(@set $access, $v, Real, $row)
    };
    (@set_if Integer Integer $access:tt, $v:ident, $row:expr) => {
        $crate::fmus::table::variables!(@set $access, $v, Integer, $row)
    };
    (@set_if Boolean Boolean $access:tt, $v:ident, $row:expr) => {
        $crate::fmus::table::variables!(@set $access, $v, Boolean, $row)
    };
    (@set_if $Ty:ident $Kind:ident $access:tt, $v:ident, $row:expr) => {
        Err($crate::fmus::table::refuse($crate::fmus::table::Value::$Ty($v)))
    };
    (@rows $rows:ident, $Var:ident, $Variant:ident, $row:expr) => {
        $rows.push(($Var::$Variant, $row))
    };
    (@rows $rows:ident, $Var:ident, $Variant:ident, $family:expr, $id:ident) => {
        $rows.extend(
            $crate::fmus::table::Family::<_, $Var>::rows(&$family)
                .into_iter()
                .map(|($id, row)| ($Var::$Variant($id), row)),
        )
    };
    (@row $Var:ident, $row:expr;) => {{
        const ROW: $crate::fmus::table::Row<$Var> = $row;
        ROW
    }};
    (@row $Var:ident, $family:expr; $id:ident) => {
        $crate::fmus::table::Family::<_, $Var>::row(&$family, $id)
    };
    (@get (get $get:expr $(, set $set:expr)?)) => { $get };
    (@get ($place:expr)) => { $place };
    (@set (get $get:expr), $v:ident, $Ty:ident, $row:expr) => {
        Err($crate::fmus::table::refuse($crate::fmus::table::Value::$Ty($v)))
    };
    (@set (get $get:expr, set $set:expr), $v:ident, $Ty:ident, $row:expr) => {{
        let ($v, outcome) = $crate::fmus::table::Admit::admit($v, &$row)?;
        $set;
        Ok(outcome)
    }};
    (@set ($place:expr), $v:ident, $Ty:ident, $row:expr) => {{
        let ($v, outcome) = $crate::fmus::table::Admit::admit($v, &$row)?;
        $place = $v;
        Ok(outcome)
    }};
    (@der $rate:ident;) => {
        Err($crate::fmi2::ModelError("not a Real input".into()))
    };
    (@der $rate:ident; $der:expr) => {{
        $der = $rate;
        Ok(())
    }};
}
pub(crate) use variables;

/// The [`crate::fmi2::Model`] methods that describe a scene's FMU, put
/// inside the `impl Model` block of a model generic over `S: Scene`: its
/// [`crate::fmi2::ModelInfo`] ([`super::common::info_for`]) and its
/// variables (the table's `all_variables()` restricted to what the scene
/// exposes, [`crate::scene::SceneSpec::variables`]).
macro_rules! scene_interface {
    () => {
        fn info() -> $crate::fmi2::ModelInfo {
            $crate::fmus::common::info_for(&S::SPEC)
        }

        fn variables() -> Vec<$crate::fmi2::ScalarVariable<Self::Var>> {
            S::SPEC.variables(all_variables())
        }
    };
}
pub(crate) use scene_interface;

/// The [`crate::fmi2::Model`] methods that read and write variables, put
/// inside a model's `impl Model` block: each goes through the model's
/// table ([`variables!`]). A variable of another type reads as NaN, 0 or
/// false; an input derivative must be finite.
macro_rules! model_access {
    () => {
        fn get_real(&self, var: Self::Var) -> f64 {
            self.table_get_real(var)
        }

        fn get_integer(&self, var: Self::Var) -> i32 {
            self.table_get_integer(var)
        }

        fn get_boolean(&self, var: Self::Var) -> bool {
            self.table_get_boolean(var)
        }

        fn set_real(
            &mut self,
            var: Self::Var,
            value: f64,
        ) -> Result<$crate::fmi2::SetOutcome, $crate::fmi2::ModelError> {
            self.table_set_real(var, value)
        }

        fn set_integer(
            &mut self,
            var: Self::Var,
            value: i32,
        ) -> Result<$crate::fmi2::SetOutcome, $crate::fmi2::ModelError> {
            self.table_set_integer(var, value)
        }

        fn set_boolean(
            &mut self,
            var: Self::Var,
            value: bool,
        ) -> Result<$crate::fmi2::SetOutcome, $crate::fmi2::ModelError> {
            self.table_set_boolean(var, value)
        }

        fn set_real_input_derivative(
            &mut self,
            var: Self::Var,
            _order: i32,
            value: f64,
        ) -> Result<(), $crate::fmi2::ModelError> {
            if !value.is_finite() {
                return Err($crate::fmi2::ModelError(format!(
                    "input derivative {value} must be finite"
                )));
            }
            self.table_set_derivative(var, value)
        }
    };
}
pub(crate) use model_access;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::Params;

    /// A toy model with one parameter and one output: adding either is one
    /// row (and, for an output, what it depends on).
    #[derive(Default)]
    struct Toy {
        gain: f64,
        y: f64,
    }

    variables! {
        /// The toy's variables.
        pub enum ToyVar;
        impl[] Toy as (m, v) {
            Gain = parameter(
                "gain",
                "A gain",
                real("1", Some(2.0), Some(Range { min: 0.0, max: 10.0 })),
                Check::Finite,
            ) => Real(m.gain);
            Y = output("y", "The gain times the input", "1", gain) => Real(get m.y);
        }
    }

    /// What `y` depends on.
    fn gain() -> Vec<ToyVar> {
        vec![ToyVar::Gain]
    }

    /// The table gives the toy its modelDescription rows (dependencies
    /// named), get and set, and the range check of the row.
    #[test]
    fn a_row_is_a_variable_with_its_get_set_and_range() {
        let vars = all_variables();
        assert_eq!(vars.len(), 2);
        let (gain, y) = (&vars[0], &vars[1]);
        assert_eq!((gain.name, gain.id), ("gain", ToyVar::Gain));
        assert_eq!(gain.causality, Causality::Parameter);
        assert_eq!(
            gain.ty,
            real(
                "1",
                Some(2.0),
                Some(Range {
                    min: 0.0,
                    max: 10.0
                })
            )
        );
        assert_eq!(
            (y.name, y.id, y.causality),
            ("y", ToyVar::Y, Causality::Output)
        );
        assert_eq!(y.depends_on, ["gain"]);

        let mut m = Toy::default();
        assert!(matches!(
            m.table_set(ToyVar::Gain, Value::Real(3.0)),
            Ok(SetOutcome::Ok)
        ));
        assert_eq!(m.table_get(ToyVar::Gain), Value::Real(3.0));
        let refused = |r: Result<SetOutcome, ModelError>| r.unwrap_err().0;
        assert_eq!(
            refused(m.table_set(ToyVar::Gain, Value::Real(11.0))),
            "gain = 11 is out of range: must be finite and in [0, 10]"
        );
        assert_eq!(m.table_get(ToyVar::Gain), Value::Real(3.0));
        assert_eq!(
            refused(m.table_set(ToyVar::Y, Value::Real(1.0))),
            "not a Real input or parameter"
        );
        assert_eq!(
            refused(m.table_set(ToyVar::Gain, Value::Boolean(true))),
            "not a Boolean parameter"
        );
        assert_eq!(
            m.table_set_derivative(ToyVar::Gain, 1.0).unwrap_err().0,
            "not a Real input"
        );
    }

    /// [`LawParameters::row`] indexes [`PARAMETERS`] by [`ParamId`]: the
    /// row it gives is the one [`Family::rows`] lists for the id.
    #[test]
    fn a_law_parameter_row_is_found_by_its_id() {
        let rows: Vec<(ParamId, Row<()>)> = LawParameters.rows();
        assert_eq!(rows.len(), PARAMETERS.len());
        for (id, row) in rows {
            let by_id: Row<()> = LawParameters.row(id);
            assert_eq!((by_id.name, by_id.ty), (row.name, row.ty));
        }
    }

    /// The shared rows refuse, clamp and name values as the models did by
    /// hand: the law's own message for its parameters, the unit interval
    /// without "finite", the activation command clamped with a warning.
    #[test]
    fn the_checks_give_the_messages_users_see() {
        let err = |r: Result<(f64, SetOutcome), ModelError>| r.unwrap_err().0;
        for info in &PARAMETERS {
            let row: Row<()> = law_parameter(info);
            let bad = info.range.max * 2.0 + 1.0;
            assert_eq!(
                err(bad.admit(&row)),
                Params::check(info.id, bad).unwrap_err().to_string()
            );
        }
        assert_eq!(
            err(f64::NAN.admit(&l0::<()>("", 1.0))),
            "L0 = NaN is out of range: must be finite and in [1e-4, 10]"
        );
        assert_eq!(
            err(2.0.admit(&initial_activation::<()>())),
            "initial_activation = 2 is out of range: must be in [0, 1]"
        );
        assert_eq!(
            err(f64::NAN.admit(&activation::<()>())),
            "activation = NaN is out of range: must be in [0, 1]"
        );
        match 1.5.admit(&activation::<()>()) {
            Ok((x, SetOutcome::Warning { message, log_once })) => {
                assert_eq!(x, 1.0);
                assert!(log_once);
                assert_eq!(
                    message,
                    "activation = 1.5 is outside [0, 1]; clamped to 1 (logged once per instance)"
                );
            }
            other => panic!("{other:?}"),
        }
        let layers: Row<()> = parameter("n", "", integer(4, (1, 96)), Check::Closed);
        assert_eq!(
            0.admit(&layers).unwrap_err().0,
            "n = 0 is out of range: must be in [1, 96]"
        );
        assert!(matches!(96.admit(&layers), Ok((96, SetOutcome::Ok))));
    }
}
