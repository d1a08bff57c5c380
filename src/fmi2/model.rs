//! The contract between the generic FMI 2.0 Co-Simulation layer and a model.
//!
//! The layer knows nothing about muscles: it owns the FMI state machine, the
//! communication time, logging, FMU states and argument checking. A model owns
//! its physics and exposes it through [`Model`] and one variable table
//! ([`Model::variables`]), which is the single source of both
//! `modelDescription.xml` and the value-reference dispatch: the value reference
//! of a variable is its index in that table.

/// FMI 2.0 causality of a scalar variable (FMI 2.0 spec, section 2.2.7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    Input,
    Output,
    Local,
    Independent,
}

/// FMI 2.0 variability of a scalar variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    Constant,
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

/// FMI 2.0 `initial` attribute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Initial {
    Exact,
    Approx,
    Calculated,
}

/// Type, start value and declared range of a scalar variable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VarType {
    Real {
        /// Name of a unit declared in [`ModelInfo::units`], if any.
        unit: Option<&'static str>,
        start: Option<f64>,
        min: Option<f64>,
        max: Option<f64>,
    },
    Integer {
        start: Option<i32>,
        min: Option<i32>,
        max: Option<i32>,
    },
    Boolean {
        start: Option<bool>,
    },
}

/// One row of a model's variable table. `V` is the model's own handle for the
/// variable (usually a small `Copy` enum); the layer hands it back to the model
/// in every get/set call, so the model never sees value references.
#[derive(Clone, Debug)]
pub struct ScalarVariable<V> {
    pub name: &'static str,
    pub description: &'static str,
    pub causality: Causality,
    pub variability: Variability,
    pub initial: Option<Initial>,
    pub ty: VarType,
    /// For outputs: the names of the inputs (and, in `InitialUnknowns`, the
    /// parameters) this output depends on. Must name variables of the same table.
    pub depends_on: Vec<&'static str>,
    pub id: V,
}

/// A unit for `<UnitDefinitions>`: name and SI base-unit exponents.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Unit {
    pub name: &'static str,
    pub kg: i32,
    pub m: i32,
    pub s: i32,
}

/// Static facts about a model that go into `modelDescription.xml`.
#[derive(Clone, Debug)]
pub struct ModelInfo {
    /// `modelName` and `modelIdentifier` (the binary is `<id>.so`).
    pub model_identifier: &'static str,
    pub description: &'static str,
    pub version: &'static str,
    pub units: Vec<Unit>,
    /// DefaultExperiment: start, stop, step size.
    pub default_experiment: (f64, f64, f64),
    /// Highest order of input derivative the model uses (canInterpolateInputs
    /// is true when this is at least 1).
    pub max_input_derivative_order: i32,
    /// Whether an input set at a communication point changes outputs at that
    /// point (FMI 2.0 section 2.2.8: `<Outputs>` dependencies are those "at
    /// Communication Points"). `false` for a model whose outputs change only in
    /// fmi2DoStep: its `<Outputs>` then list no dependencies, while
    /// `<InitialUnknowns>` keep the `depends_on` of each output.
    pub direct_feedthrough: bool,
}

/// Error raised by a model; the layer logs the message (prefixed with the
/// variable name where there is one) and returns `fmi2Error`.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelError(pub String);

impl<S: Into<String>> From<S> for ModelError {
    fn from(s: S) -> Self {
        ModelError(s.into())
    }
}

/// Successful outcome of a set call.
#[derive(Clone, Debug, PartialEq)]
pub enum SetOutcome {
    Ok,
    /// The value was accepted after an adjustment (e.g. clamped into range);
    /// the layer returns `fmi2Warning` and logs the message. `log_once` asks the
    /// layer to log this kind of warning only once per instance (status is
    /// still `fmi2Warning` every time).
    Warning {
        message: String,
        log_once: bool,
    },
}

/// Outcome of a failed step.
#[derive(Clone, Debug, PartialEq)]
pub enum StepError {
    /// The step could not be completed; the model is unchanged (exactly as
    /// before the call). The layer returns `fmi2Discard`.
    Discard(String),
    /// Unrecoverable; the layer returns `fmi2Error`.
    Error(String),
}

/// A model the generic FMI 2.0 Co-Simulation layer can export.
///
/// Every method that fails must leave `self` exactly as it was: the layer
/// relies on that to keep the instance's last good state.
pub trait Model: Clone + Send + 'static {
    /// The model's handle for one of its variables.
    type Var: Copy + Send + Sync + std::fmt::Debug + 'static;

    fn info() -> ModelInfo;

    /// The variable table. Value reference = index in this vector.
    fn variables() -> Vec<ScalarVariable<Self::Var>>;

    /// A fresh model: every variable at its start value.
    fn new() -> Self;

    /// Called only for Real variables.
    fn get_real(&self, var: Self::Var) -> f64;
    /// Called only for Integer variables.
    fn get_integer(&self, var: Self::Var) -> i32;
    /// Called only for Boolean variables.
    fn get_boolean(&self, var: Self::Var) -> bool;

    /// Called only for Real inputs and parameters, in a state where the FMI
    /// standard allows the set. The model checks the value's range.
    fn set_real(&mut self, var: Self::Var, value: f64) -> Result<SetOutcome, ModelError>;
    fn set_integer(&mut self, var: Self::Var, value: i32) -> Result<SetOutcome, ModelError>;
    fn set_boolean(&mut self, var: Self::Var, value: bool) -> Result<SetOutcome, ModelError>;

    /// `fmi2SetRealInputDerivatives` for one Real input; `order` is in
    /// 1..=`info().max_input_derivative_order` (checked by the layer).
    fn set_real_input_derivative(
        &mut self,
        var: Self::Var,
        order: i32,
        value: f64,
    ) -> Result<(), ModelError>;

    /// Make all outputs consistent with the current parameters and inputs at
    /// the start of the simulation (validates parameters). Called at
    /// `fmi2ExitInitializationMode` and before outputs are read in
    /// initialization mode after a set.
    fn initialize(&mut self) -> Result<(), ModelError>;

    /// Advance from `t` to `t + h` with the inputs currently set. On error the
    /// model must be unchanged.
    fn do_step(&mut self, t: f64, h: f64) -> Result<(), StepError>;

    /// Partial derivative of output `unknown` with respect to input `known`
    /// of the map that produced the current outputs (the last step, or the
    /// initial equilibrium). Used by `fmi2GetDirectionalDerivative`.
    fn partial_derivative(&self, unknown: Self::Var, known: Self::Var) -> Result<f64, ModelError>;

    /// Whether the model holds the state of an initialized simulation (the
    /// initial equilibrium or a later step's). A deserialized FMU state whose
    /// layer has left initialization mode must have one; models whose state
    /// exists from construction keep the default.
    fn is_initialized(&self) -> bool {
        true
    }

    /// For a deserialized FMU state whose layer is stepping, where no
    /// parameter can have changed since the outputs were committed: `Err`
    /// naming the first output that the model's parameters and committed
    /// state do not give. Models whose outputs are all checked at decoding
    /// keep the default.
    fn check_stepping_outputs(&self) -> Result<(), String> {
        Ok(())
    }

    /// Append the complete model state (parameters, inputs, history) as bytes.
    fn serialize(&self, out: &mut Vec<u8>);
    /// Rebuild a model from bytes written by [`Model::serialize`]; advances `input`.
    fn deserialize(input: &mut &[u8]) -> Result<Self, ModelError>;
}
