//! The outputs both muscles compute, named once. [`muscle_outputs!`]
//! declares a muscle's output enum: these first, in this order (the order
//! of the FMUs' output rows and of the muscles' stored outputs), then the
//! muscle's own. Imports nothing.

/// How many outputs both muscles have: the first variants of each
/// muscle's output enum.
pub const N_SHARED: usize = 9;

/// `enum NAME { OWN, … }` (Clone, Copy, Debug, PartialEq, Eq) with the
/// shared outputs as its first [`N_SHARED`] variants, then `OWN`, …: each
/// muscle's doc says how it measures the shared ones.
macro_rules! muscle_outputs {
    (
        $(#[$attr:meta])*
        $vis:vis enum $Name:ident { $( $(#[$own_attr:meta])* $own:ident, )* }
    ) => {
        $(#[$attr])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        $vis enum $Name {
            /// Axial force on the moved end, tension positive.
            Force,
            /// Engineering (nominal) stress: force / area.
            Stress,
            /// Axial Cauchy (true) stress.
            CauchyStress,
            /// Activation level a.
            ActivationLevel,
            /// Modified fibre stretch J^(-1/3) λ.
            FibreStretch,
            /// Contractile element stretch λ_m.
            CeStretch,
            /// Series elastic element stretch λ_s.
            SeeStretch,
            /// SEE (= CE) stress σ_s.
            ActiveStress,
            /// Stress − active stress.
            PassiveStress,
            $( $(#[$own_attr])* $own, )*
        }
    };
}
pub(crate) use muscle_outputs;

#[cfg(test)]
mod tests {
    use super::*;

    muscle_outputs! {
        /// A muscle with one output of its own.
        #[allow(dead_code)]
        enum Toy {
            Own,
        }
    }

    /// The shared outputs come first, [`N_SHARED`] of them, in their
    /// order; a muscle's own follow.
    #[test]
    fn the_shared_outputs_come_first() {
        assert_eq!(Toy::Force as usize, 0);
        assert_eq!(Toy::PassiveStress as usize, N_SHARED - 1);
        assert_eq!(Toy::Own as usize, N_SHARED);
    }
}
