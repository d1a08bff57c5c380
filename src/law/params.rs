//! The 14 material parameters of the law (MODEL_NOTES "Parameters", paper Table 2),
//! their defaults, units and valid ranges, validated as a whole.

use std::fmt;

/// Identifies one law parameter. The order is the order of MODEL_NOTES' table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamId {
    B,
    C,
    Alpha,
    Beta,
    A,
    Sigma0,
    S,
    Kc,
    Ke,
    D,
    LambdaDotMin,
    LambdaOpt,
    Dcomp,
    K,
}

/// Valid range of a parameter: a closed interval `[min, max]` of finite values.
///
/// The bounds are physical, not numerical conveniences: wide enough for every
/// muscle the paper's ranges and the stiff-case grid of the stability matrix
/// cover (several decades beyond both), narrow enough that no derived quantity
/// of the law (SEE stiffness `alpha*beta`, `exp(b (I1bar - 3))` over the law's
/// stretch range, `1/L0`) can overflow or underflow to zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    pub min: f64,
    pub max: f64,
}

impl Range {
    /// Whether the value is finite and lies in `[min, max]`. Implements no
    /// equation: the range check of a parameter of MODEL_NOTES "Parameters".
    pub fn contains(self, x: f64) -> bool {
        x.is_finite() && x >= self.min && x <= self.max
    }

    /// `v` of the variable `name` in the range, else the [`out_of_range`]
    /// message naming it (no equation).
    pub fn check(self, name: &str, v: f64) -> Result<(), String> {
        if self.contains(v) {
            Ok(())
        } else {
            Err(out_of_range(name, v, self))
        }
    }
}

/// The message of a value `v` of the variable `name` outside what it must
/// be (`must`: a [`Range`], "in [0, 1]", ...): every range violation the
/// models report reads "`name` = `v` is out of range: must be `must`".
pub fn out_of_range(
    name: impl fmt::Display,
    v: impl fmt::Display,
    must: impl fmt::Display,
) -> String {
    format!("{name} = {v} is out of range: must be {must}")
}

impl fmt::Display for Range {
    /// "finite and in [min, max]", for messages (no equation).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "finite and in [{}, {}]",
            Bound(self.min),
            Bound(self.max)
        )
    }
}

/// A bound of a range as a message shows it: plain decimals from 1e-3 to
/// 1e4 (`0`, `0.95`, `2`, `100`), else exponent form (`1e9`, `1e-15`,
/// `inf`). For messages; no equation.
#[derive(Clone, Copy, Debug)]
pub struct Bound(pub f64);

impl fmt::Display for Bound {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        if x == 0.0 || (1e-3..1e4).contains(&x.abs()) {
            write!(f, "{x}")
        } else {
            write!(f, "{x:e}")
        }
    }
}

/// The range `[min, max]` (no equation; the tables' shorthand).
const fn between(min: f64, max: f64) -> Range {
    Range { min, max }
}

/// Valid range of a muscle's rest length `L0` (m): from a 0.1 mm fibre bundle
/// to a 10 m cable; `1/L0` and `L0 * stretch` stay far from overflow.
pub const L0_RANGE: Range = between(1e-4, 10.0);

/// Valid range of the `length` input (m): a tenth of the shortest `L0` to ten
/// times the longest, so every stretch length/L0 in [0.1, 10] is accepted for
/// every `L0` (the law's evaluable stretches at the default b are about
/// [0.061, 5.70], `uniaxial::evaluable_stretch_range`). Whether the law can be
/// solved at a given length/L0 depends on the parameters and is the step's to
/// judge (fmi2Discard with the evaluable range in the message).
pub const LENGTH_RANGE: Range = between(1e-5, 100.0);

/// Valid range of a reference cross-section `area` (m²).
pub const AREA_RANGE: Range = between(1e-10, 1.0);

/// Name, default, unit, valid range and meaning of one parameter; `Id`
/// names the table it belongs to ([`ParamId`] for the law's,
/// [`TendonParamId`] for the musculotendon unit's).
#[derive(Clone, Copy, Debug)]
pub struct ParamInfo<Id = ParamId> {
    pub id: Id,
    /// The name used in code and in the FMUs (MODEL_NOTES "name in code/FMU").
    pub name: &'static str,
    pub default: f64,
    /// Unit name as declared in the FMUs' UnitDefinitions ("1" when dimensionless).
    pub unit: &'static str,
    pub range: Range,
    pub description: &'static str,
}

/// The parameter table: the single source of names, defaults, units and ranges.
pub const PARAMETERS: [ParamInfo; 14] = [
    ParamInfo {
        id: ParamId::B,
        name: "b",
        default: 23.46,
        unit: "1",
        range: between(1e-3, 100.0),
        description: "Matrix exponent b of U_I = c (exp(b (I1bar - 3)) - 1)",
    },
    ParamInfo {
        id: ParamId::C,
        name: "c",
        default: 379.0,
        unit: "Pa",
        range: between(1e-3, 1e8),
        description: "Matrix stiffness c",
    },
    ParamInfo {
        id: ParamId::Alpha,
        name: "alpha",
        default: 10.0,
        unit: "1",
        range: between(0.1, 1e4),
        description: "SEE exponent alpha (eq 6)",
    },
    ParamInfo {
        id: ParamId::Beta,
        name: "beta",
        default: 1.0e3,
        unit: "Pa",
        range: between(1e-3, 1e9),
        description: "SEE stress offset beta (eq 6)",
    },
    ParamInfo {
        id: ParamId::A,
        name: "A",
        default: 4.0,
        unit: "1",
        range: between(0.0, 1e3),
        description: "PE coefficient A (eq 22-23)",
    },
    ParamInfo {
        id: ParamId::Sigma0,
        name: "sigma0",
        default: 7.0e5,
        unit: "Pa",
        range: between(1.0, 1e9),
        description: "Maximum isometric stress sigma0 (paper range 0.16-1.0 MPa)",
    },
    ParamInfo {
        id: ParamId::S,
        name: "S",
        default: 50.0,
        unit: "1/s",
        range: between(1e-3, 1e7),
        description: "Activation rate S (eq 9-10)",
    },
    ParamInfo {
        id: ParamId::Kc,
        name: "kc",
        default: 5.0,
        unit: "1",
        range: between(1e-2, 1e3),
        description: "Concentric force-velocity shape k_c (paper range 4.0-5.88)",
    },
    ParamInfo {
        id: ParamId::Ke,
        name: "ke",
        default: 5.0,
        unit: "1",
        range: between(1e-2, 1e3),
        description: "Eccentric force-velocity shape k_e (paper range 3.14-7.56)",
    },
    ParamInfo {
        id: ParamId::D,
        name: "d",
        default: 1.5,
        unit: "1",
        range: between(1.0, 100.0),
        description: "Eccentric force-velocity offset d (paper range 1.1-1.8)",
    },
    ParamInfo {
        id: ParamId::LambdaDotMin,
        name: "lambda_dot_min",
        default: -17.0,
        unit: "1/s",
        range: between(-1e4, -1e-6),
        description: "Minimum (most negative) CE stretch rate",
    },
    ParamInfo {
        id: ParamId::LambdaOpt,
        name: "lambda_opt",
        default: 1.05,
        unit: "1",
        range: between(0.5, 2.0),
        description: "Optimal fibre stretch (eq 11)",
    },
    ParamInfo {
        id: ParamId::Dcomp,
        name: "D",
        default: 1.0e-9,
        unit: "1/Pa",
        range: between(1e-15, 1e-2),
        description: "Compressibility D (bulk modulus 2/D)",
    },
    ParamInfo {
        id: ParamId::K,
        name: "k",
        default: 0.3,
        unit: "1",
        range: between(1e-3, 1e3),
        description: "SEE-to-CE rest length ratio k = L_SEE,0 / L_CE,0",
    },
];

/// Identifies one parameter of the musculotendon unit (MODEL_NOTES
/// "Musculotendon unit"): the tendon and the pennation in series with the
/// muscle. Not law parameters: only a musculotendon model exposes them.
/// (Whether the tendon is compliant is a switch, not a real parameter:
/// `law::musculotendon::UnitParams::compliant_tendon`.)
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TendonParamId {
    TendonSlackLength,
    TendonStrainAtF0,
    PennationAngle,
}

/// The musculotendon unit's parameter table (MODEL_NOTES "Musculotendon
/// unit"): the single source of their names, defaults, units and ranges.
/// The ranges are physical: slack lengths of the same span as `L0`
/// ([`L0_RANGE`]); strains at F0 from a practically rigid 1e-6 to 1 (real
/// tendons: 0.03–0.1), so that the toe and linear slopes (~1.7/ε0) stay far
/// from overflow; pennation angles at `L0` from 0 to 1 rad (57°, within
/// MODEL_NOTES' [0°, 60°); real muscles stay below ~35°).
pub const TENDON_PARAMETERS: [ParamInfo<TendonParamId>; 3] = [
    ParamInfo {
        id: TendonParamId::TendonSlackLength,
        name: "tendon_slack_length",
        default: 0.05,
        unit: "m",
        range: L0_RANGE,
        description: "Tendon slack length L_TS: the tendon carries force when longer",
    },
    ParamInfo {
        id: TendonParamId::TendonStrainAtF0,
        name: "tendon_strain_at_F0",
        default: 0.04,
        unit: "1",
        range: between(1e-6, 1.0),
        description: "Tendon strain eps0 at the maximum isometric force F0 (Thelen 2003)",
    },
    ParamInfo {
        id: TendonParamId::PennationAngle,
        name: "pennation_angle",
        default: 0.0,
        unit: "rad",
        range: between(0.0, 1.0),
        description: "Pennation angle alpha0 of the fibres at fibre length L0 (constant thickness)",
    },
];

/// An invalid parameter value: names the parameter, the value and the valid range.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamError {
    pub name: &'static str,
    pub value: f64,
    pub range: Range,
}

impl fmt::Display for ParamError {
    /// The message naming the parameter, its value and its range (no equation).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&out_of_range(
            format_args!("parameter {}", self.name),
            self.value,
            self.range,
        ))
    }
}

impl std::error::Error for ParamError {}

/// The material parameters (MODEL_NOTES "Parameters"; SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// Matrix exponent b.
    pub b: f64,
    /// Matrix stiffness c [Pa].
    pub c: f64,
    /// SEE exponent α.
    pub alpha: f64,
    /// SEE stress offset β [Pa].
    pub beta: f64,
    /// PE coefficient A.
    pub a_pe: f64,
    /// Maximum isometric stress σ0 [Pa].
    pub sigma0: f64,
    /// Activation rate S [1/s].
    pub s: f64,
    /// Concentric f-v shape k_c.
    pub kc: f64,
    /// Eccentric f-v shape k_e.
    pub ke: f64,
    /// Eccentric f-v offset d.
    pub d: f64,
    /// Minimum CE stretch rate λ̇_m^min [1/s] (negative).
    pub lambda_dot_min: f64,
    /// Optimal fibre stretch λ_opt.
    pub lambda_opt: f64,
    /// Compressibility D [1/Pa].
    pub d_comp: f64,
    /// SEE-to-CE rest length ratio k.
    pub k: f64,
}

impl Default for Params {
    /// Paper Table 2 defaults (MODEL_NOTES "Parameters").
    fn default() -> Self {
        let mut p = Params {
            b: 0.0,
            c: 0.0,
            alpha: 0.0,
            beta: 0.0,
            a_pe: 0.0,
            sigma0: 0.0,
            s: 0.0,
            kc: 0.0,
            ke: 0.0,
            d: 0.0,
            lambda_dot_min: 0.0,
            lambda_opt: 0.0,
            d_comp: 0.0,
            k: 0.0,
        };
        for info in &PARAMETERS {
            *p.get_mut(info.id) = info.default;
        }
        p
    }
}

impl Params {
    /// The table row of a parameter (MODEL_NOTES "Parameters"; no equation).
    pub fn info(id: ParamId) -> &'static ParamInfo {
        PARAMETERS
            .iter()
            .find(|p| p.id == id)
            .expect("every ParamId has a row in PARAMETERS")
    }

    /// Value of one parameter of MODEL_NOTES "Parameters" (no equation).
    pub fn get(&self, id: ParamId) -> f64 {
        match id {
            ParamId::B => self.b,
            ParamId::C => self.c,
            ParamId::Alpha => self.alpha,
            ParamId::Beta => self.beta,
            ParamId::A => self.a_pe,
            ParamId::Sigma0 => self.sigma0,
            ParamId::S => self.s,
            ParamId::Kc => self.kc,
            ParamId::Ke => self.ke,
            ParamId::D => self.d,
            ParamId::LambdaDotMin => self.lambda_dot_min,
            ParamId::LambdaOpt => self.lambda_opt,
            ParamId::Dcomp => self.d_comp,
            ParamId::K => self.k,
        }
    }

    /// The field of one parameter of MODEL_NOTES "Parameters" (no equation).
    fn get_mut(&mut self, id: ParamId) -> &mut f64 {
        match id {
            ParamId::B => &mut self.b,
            ParamId::C => &mut self.c,
            ParamId::Alpha => &mut self.alpha,
            ParamId::Beta => &mut self.beta,
            ParamId::A => &mut self.a_pe,
            ParamId::Sigma0 => &mut self.sigma0,
            ParamId::S => &mut self.s,
            ParamId::Kc => &mut self.kc,
            ParamId::Ke => &mut self.ke,
            ParamId::D => &mut self.d,
            ParamId::LambdaDotMin => &mut self.lambda_dot_min,
            ParamId::LambdaOpt => &mut self.lambda_opt,
            ParamId::Dcomp => &mut self.d_comp,
            ParamId::K => &mut self.k,
        }
    }

    /// Set one parameter of MODEL_NOTES "Parameters" after checking it against
    /// its range; on error `self` is unchanged (no equation).
    pub fn set(&mut self, id: ParamId, value: f64) -> Result<(), ParamError> {
        Self::check(id, value)?;
        *self.get_mut(id) = value;
        Ok(())
    }

    /// Check one value against the range of parameter `id` (MODEL_NOTES
    /// "Parameters"; no equation).
    pub fn check(id: ParamId, value: f64) -> Result<(), ParamError> {
        let info = Self::info(id);
        if info.range.contains(value) {
            Ok(())
        } else {
            Err(ParamError {
                name: info.name,
                value,
                range: info.range,
            })
        }
    }

    /// Validate the whole set (every parameter of MODEL_NOTES "Parameters" in
    /// its range); reports the first offender in table order (no equation).
    pub fn validate(&self) -> Result<(), ParamError> {
        PARAMETERS
            .iter()
            .try_for_each(|info| Self::check(info.id, self.get(info.id)))
    }

    /// Construct from explicit values, validated (see [`Params::validate`];
    /// no equation).
    pub fn new_validated(p: Params) -> Result<Params, ParamError> {
        p.validate()?;
        Ok(p)
    }

    /// Asymptote of the force-velocity curve (paper eq 12) for fast lengthening,
    /// d + (d − 1)/(k_e k_c) (MODEL_NOTES "Hill fibre").
    pub fn fv_max(&self) -> f64 {
        self.d + (self.d - 1.0) / (self.ke * self.kc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_read_as_plain_numbers_in_messages() {
        let shown = |min, max| between(min, max).to_string();
        assert_eq!(shown(0.0, 0.95), "finite and in [0, 0.95]");
        assert_eq!(shown(0.5, 2.0), "finite and in [0.5, 2]");
        assert_eq!(shown(1.0, 1e9), "finite and in [1, 1e9]");
        assert_eq!(shown(1e-15, 1e-2), "finite and in [1e-15, 0.01]");
        assert_eq!(shown(-17.0, 1e4), "finite and in [-17, 1e4]");
        assert_eq!(Bound(f64::INFINITY).to_string(), "inf");
    }

    #[test]
    fn defaults_are_table_2_and_valid() {
        let p = Params::default();
        assert_eq!(p.b, 23.46);
        assert_eq!(p.c, 379.0);
        assert_eq!(p.alpha, 10.0);
        assert_eq!(p.beta, 1.0e3);
        assert_eq!(p.a_pe, 4.0);
        assert_eq!(p.sigma0, 7.0e5);
        assert_eq!(p.s, 50.0);
        assert_eq!(p.kc, 5.0);
        assert_eq!(p.ke, 5.0);
        assert_eq!(p.d, 1.5);
        assert_eq!(p.lambda_dot_min, -17.0);
        assert_eq!(p.lambda_opt, 1.05);
        assert_eq!(p.d_comp, 1.0e-9);
        assert_eq!(p.k, 0.3);
        assert!(p.validate().is_ok());
    }

    #[test]
    fn every_bad_value_is_rejected_with_name_and_range() {
        let bad: &[(ParamId, f64)] = &[
            (ParamId::B, 0.0),
            (ParamId::C, -1.0),
            (ParamId::Alpha, 0.0),
            (ParamId::Beta, 0.0),
            (ParamId::A, -0.1),
            (ParamId::Sigma0, 0.0),
            (ParamId::S, 0.0),
            (ParamId::Kc, 0.0),
            (ParamId::Ke, -2.0),
            (ParamId::D, 0.99),
            (ParamId::LambdaDotMin, 0.0),
            (ParamId::LambdaOpt, 0.0),
            (ParamId::Dcomp, 0.0),
            (ParamId::K, 0.0),
        ];
        for &(id, v) in bad {
            for value in [v, f64::NAN, f64::INFINITY] {
                let mut p = Params::default();
                let before = p;
                let err = p.set(id, value).unwrap_err();
                assert_eq!(p, before, "a rejected set must change nothing");
                let msg = err.to_string();
                assert!(msg.contains(Params::info(id).name), "{msg}");
                assert!(msg.contains("must be"), "{msg}");
                // The whole-set validator catches the same value.
                *p.get_mut(id) = value;
                assert_eq!(p.validate().unwrap_err().name, Params::info(id).name);
            }
        }
    }

    #[test]
    fn names_are_unique() {
        for (i, a) in PARAMETERS.iter().enumerate() {
            for b in &PARAMETERS[i + 1..] {
                assert_ne!(a.name, b.name);
                assert_ne!(a.id, b.id);
            }
        }
    }
}
