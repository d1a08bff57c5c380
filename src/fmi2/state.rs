//! The FMI 2.0 Co-Simulation state machine (FMI 2.0 spec, section 4.2.4
//! "State Machine of Calling Sequence from Master to Slave") and its table of
//! the states in which each function may be called.
//!
//! Steps run synchronously (`canRunAsynchronuously = false`), so
//! `stepInProgress` is never entered and `fmi2DoStep` never returns
//! `fmi2Pending`; `stepCanceled` is modelled but unreachable for the same
//! reason. The start/end pseudo-state is "no instance".

/// State of one instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FmiState {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    StepCanceled,
    Terminated,
    Error,
    Fatal,
}

impl FmiState {
    /// Every state, in code order ([`FmiState::to_u8`]).
    pub const ALL: [FmiState; 8] = [
        FmiState::Instantiated,
        FmiState::InitializationMode,
        FmiState::StepComplete,
        FmiState::StepFailed,
        FmiState::StepCanceled,
        FmiState::Terminated,
        FmiState::Error,
        FmiState::Fatal,
    ];

    /// The name used in the FMI 2.0 state table.
    pub fn name(self) -> &'static str {
        match self {
            FmiState::Instantiated => "instantiated",
            FmiState::InitializationMode => "initializationMode",
            FmiState::StepComplete => "stepComplete",
            FmiState::StepFailed => "stepFailed",
            FmiState::StepCanceled => "stepCanceled",
            FmiState::Terminated => "terminated",
            FmiState::Error => "error",
            FmiState::Fatal => "fatal",
        }
    }

    const fn bit(self) -> u16 {
        1 << (self as u16)
    }

    /// Stable code for serialized FMU states.
    pub fn to_u8(self) -> u8 {
        self as u8
    }

    /// Inverse of [`FmiState::to_u8`].
    pub fn from_u8(v: u8) -> Option<Self> {
        Some(match v {
            0 => FmiState::Instantiated,
            1 => FmiState::InitializationMode,
            2 => FmiState::StepComplete,
            3 => FmiState::StepFailed,
            4 => FmiState::StepCanceled,
            5 => FmiState::Terminated,
            6 => FmiState::Error,
            7 => FmiState::Fatal,
            _ => return None,
        })
    }
}

/// A set of [`FmiState`]s.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateSet(u16);

impl StateSet {
    pub const fn of(states: &[FmiState]) -> Self {
        let mut bits = 0;
        let mut i = 0;
        while i < states.len() {
            bits |= states[i].bit();
            i += 1;
        }
        StateSet(bits)
    }

    #[inline(always)]
    pub const fn contains(self, s: FmiState) -> bool {
        self.0 & s.bit() != 0
    }

    /// The states of [`FmiState::ALL`] for which `f` holds.
    pub fn filter(f: impl Fn(FmiState) -> bool) -> Self {
        StateSet(
            FmiState::ALL
                .iter()
                .filter(|&&s| f(s))
                .fold(0, |bits, s| bits | s.bit()),
        )
    }
}

use FmiState::{
    Error as E, InitializationMode as IM, Instantiated as I, StepCanceled as SCa,
    StepComplete as SC, StepFailed as SF, Terminated as T,
};

/// `fmi2SetDebugLogging`: every state of an existing instance but `fatal`.
pub const SET_DEBUG_LOGGING: StateSet = StateSet::of(&[I, IM, SC, SF, SCa, T, E]);
/// `fmi2FreeInstance` per the table (this layer frees in `fatal` too, see
/// [`crate::fmi2::api::free_instance`]).
pub const FREE_INSTANCE: StateSet = StateSet::of(&[I, IM, SC, SF, SCa, T, E]);
/// `fmi2SetupExperiment`.
pub const SETUP_EXPERIMENT: StateSet = StateSet::of(&[I]);
/// `fmi2EnterInitializationMode`.
pub const ENTER_INITIALIZATION_MODE: StateSet = StateSet::of(&[I]);
/// `fmi2ExitInitializationMode`.
pub const EXIT_INITIALIZATION_MODE: StateSet = StateSet::of(&[IM]);
/// `fmi2Terminate`.
pub const TERMINATE: StateSet = StateSet::of(&[SC, SF]);
/// `fmi2Reset`.
pub const RESET: StateSet = StateSet::of(&[I, IM, SC, SF, SCa, T, E]);
/// `fmi2GetReal/Integer/Boolean/String`.
pub const GET_VALUES: StateSet = StateSet::of(&[IM, SC, SF, SCa, T, E]);
/// `fmi2SetReal/Integer/Boolean/String` (which variables: see
/// [`crate::fmi2::rules::settable_in`]).
pub const SET_VALUES: StateSet = StateSet::of(&[I, IM, SC]);
/// `fmi2GetFMUstate`, `fmi2SetFMUstate`, `fmi2FreeFMUstate`,
/// `fmi2SerializedFMUstateSize`, `fmi2SerializeFMUstate`,
/// `fmi2DeSerializeFMUstate`.
pub const FMU_STATE: StateSet = StateSet::of(&[I, IM, SC, SF, SCa, T, E]);
/// `fmi2GetDirectionalDerivative`.
pub const GET_DIRECTIONAL_DERIVATIVE: StateSet = StateSet::of(&[IM, SC, SF, SCa, T, E]);
/// `fmi2SetRealInputDerivatives`.
pub const SET_REAL_INPUT_DERIVATIVES: StateSet = StateSet::of(&[I, IM, SC]);
/// `fmi2GetRealOutputDerivatives`.
pub const GET_REAL_OUTPUT_DERIVATIVES: StateSet = StateSet::of(&[SC, SF, SCa, T, E]);
/// `fmi2DoStep`.
pub const DO_STEP: StateSet = StateSet::of(&[SC]);
/// `fmi2CancelStep`: only `stepInProgress`, which this layer never enters.
pub const CANCEL_STEP: StateSet = StateSet::of(&[]);
/// `fmi2GetStatus`, `fmi2GetRealStatus`, `fmi2GetIntegerStatus`,
/// `fmi2GetBooleanStatus`, `fmi2GetStringStatus` (plus `stepInProgress`).
pub const GET_STATUS: StateSet = StateSet::of(&[SC, SF, T]);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip() {
        for s in [I, IM, SC, SF, SCa, T, E, FmiState::Fatal] {
            assert_eq!(FmiState::from_u8(s.to_u8()), Some(s));
        }
        assert_eq!(FmiState::from_u8(8), None);
        for (i, s) in FmiState::ALL.iter().enumerate() {
            assert_eq!(s.to_u8() as usize, i);
        }
    }

    #[test]
    fn nothing_allowed_in_fatal() {
        for set in [
            SET_DEBUG_LOGGING,
            RESET,
            GET_VALUES,
            SET_VALUES,
            FMU_STATE,
            GET_DIRECTIONAL_DERIVATIVE,
            DO_STEP,
            GET_STATUS,
        ] {
            assert!(!set.contains(FmiState::Fatal));
        }
    }
}
