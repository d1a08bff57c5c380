//! Compile-time selection of the law's components (scenes).
//!
//! A [`Components`] type says which terms of the energy U = U_I + U_f + U_J
//! (MODEL_NOTES "Energy and stress") and which parts of the Hill fibre
//! (MODEL_NOTES "Hill fibre") a computation includes. The law's solvers are
//! generic over it ([`super::uniaxial::solve_uniaxial_with`],
//! [`super::hill_fibre::fibre_response_with`]), so an absent component's code
//! is not compiled into a scene's binary. [`FullLaw`] is the complete law, and
//! the non-generic entry points ([`super::solve_uniaxial`],
//! [`super::fibre_response`]) use it: their results are unchanged.

/// Which components of the law a computation includes. Every constant
/// defaults to `true` (the complete law).
pub trait Components: 'static {
    /// The isotropic matrix U_I = c (exp(b (Ī1 − 3)) − 1) (paper eq 3).
    /// Without it U_I' = U_I'' = 0.
    const MATRIX: bool = true;
    /// The parallel element σ_p = σ0 A (λ̄f − 1)² (eq 22–23). Without it
    /// σ_p = 0.
    const PARALLEL: bool = true;
    /// The contractile element in series with the series elastic element
    /// (eq 6–21; they exist only together: the CE–SEE solve). Without them
    /// σ_s = 0 and λs = 1 in closed form (MODEL_NOTES "Hill fibre": "When
    /// σ0 a f_λ = 0 the CE carries nothing"), whatever the activation.
    const CONTRACTILE: bool = true;
    /// The shortening branch of f_v (λ̇m ≤ 0, eq 12). Without it f_v = 1
    /// there ([`super::force_velocity::force_velocity_with`]).
    const FV_SHORTENING: bool = true;
    /// The lengthening branch of f_v (λ̇m > 0, eq 12). Without it f_v = 1
    /// there.
    const FV_LENGTHENING: bool = true;
    /// First-order activation dynamics da/dt = S (u − a) (MODEL_NOTES
    /// "Activation", eq 9–10). Without it a = u, whatever a model's switch
    /// says.
    const ACTIVATION_DYNAMICS: bool = true;
    /// The activation command u is an input of the computation. Without it
    /// u = 0, and no derivative with respect to it is formed.
    const ACTIVATION_INPUT: bool = true;
}

/// The complete law.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FullLaw;

impl Components for FullLaw {}
