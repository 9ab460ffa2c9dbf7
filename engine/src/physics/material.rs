//! Work materials: mechanistic cutting coefficients, optional tool-life constants, and
//! where each number comes from. The built-in library holds only rows with a cited source
//! (docs/reference.md); everything else is user-defined.

use serde::{Deserialize, Serialize};

use super::life::TaylorLife;
use super::PhysicsError;

/// Mechanistic (linear edge-force) cutting coefficients.
///
/// Cutting terms in N/mm² (multiply chip area, mm²), edge terms in N/mm (multiply edge
/// length, mm). Signs are not restricted: identified axial coefficients are sometimes
/// negative in the literature.
///
/// The size effect (optional): with exponents `mtc`, `mrc`, `mac` in [0, 0.9) each cutting
/// coefficient is Kienzle's exponential form K(h) = K·h^(−m), h the chip thickness in mm
/// (so `ktc` is the value at a 1 mm chip, Kienzle's k1.1), and the force K·h^(1−m)·b grows
/// more slowly than the chip: the measured radial force flattens with feed. All three 0
/// (the default) is the linear model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuttingCoefficients {
    pub ktc: f64,
    pub krc: f64,
    pub kac: f64,
    pub kte: f64,
    pub kre: f64,
    pub kae: f64,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mtc: f64,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mrc: f64,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mac: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The largest size-effect exponent taken: at m → 1 the cutting force would no longer grow
/// with the chip (published Kienzle exponents are 0.15–0.4).
pub const MAX_SIZE_EXPONENT: f64 = 0.9;

impl CuttingCoefficients {
    /// The linear model's six coefficients (ktc, krc, kac, kte, kre, kae).
    pub fn linear(k: [f64; 6]) -> CuttingCoefficients {
        CuttingCoefficients {
            ktc: k[0],
            krc: k[1],
            kac: k[2],
            kte: k[3],
            kre: k[4],
            kae: k[5],
            ..Default::default()
        }
    }

    /// Whether the cutting coefficients depend on the chip (a size-effect exponent is set).
    pub fn has_size_effect(&self) -> bool {
        self.mtc != 0.0 || self.mrc != 0.0 || self.mac != 0.0
    }

    /// The tangential and radial cutting coefficients a linear (stability) model takes at the
    /// operating chip `h` (mm): the tangent dF/dh = (1 − m)·K·h^(−m) of the size effect,
    /// because regenerative chatter is driven by the force's change with a small change of
    /// the chip around its mean; (ktc, krc) themselves without a size effect.
    pub fn linearized_at(&self, h: f64) -> (f64, f64) {
        if !self.has_size_effect() || !(h > 0.0 && h.is_finite()) {
            return (self.ktc, self.krc);
        }
        (
            (1.0 - self.mtc) * self.ktc * h.powf(-self.mtc),
            (1.0 - self.mrc) * self.krc * h.powf(-self.mrc),
        )
    }

    /// The size-effect exponents (mtc, mrc, mac).
    pub fn exponents(&self) -> [f64; 3] {
        [self.mtc, self.mrc, self.mac]
    }

    /// All six must be finite numbers and the exponents in [0, 0.9); names the first one
    /// that is not.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        for (field, v) in [
            ("ktc", self.ktc),
            ("krc", self.krc),
            ("kac", self.kac),
            ("kte", self.kte),
            ("kre", self.kre),
            ("kae", self.kae),
        ] {
            super::finite(field, v)?;
        }
        for (field, m) in [("mtc", self.mtc), ("mrc", self.mrc), ("mac", self.mac)] {
            if !(m.is_finite() && (0.0..MAX_SIZE_EXPONENT).contains(&m)) {
                return Err(PhysicsError::invalid(
                    field,
                    format!(
                        "{m} is not a size-effect exponent: must be in [0, {MAX_SIZE_EXPONENT})"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// As [`validate`](Self::validate), and within what a work material can have: the
    /// check on a user's material (the force model itself takes any finite numbers).
    pub fn validate_range(&self) -> Result<(), PhysicsError> {
        // Bounds no metal comes near (the hardest superalloys cut at a few thousand N/mm²):
        // past them a value is a typo or a unit mistake, and forces, power and energy would
        // be nonsense (or overflow) rather than an error.
        self.validate()?;
        const CUTTING: f64 = 20_000.0; // N/mm²
        const EDGE: f64 = 2_000.0; // N/mm
        for (field, v, lo, hi) in [
            ("ktc", self.ktc, f64::MIN_POSITIVE, CUTTING),
            ("krc", self.krc, -CUTTING, CUTTING),
            ("kac", self.kac, -CUTTING, CUTTING),
            ("kte", self.kte, -EDGE, EDGE),
            ("kre", self.kre, -EDGE, EDGE),
            ("kae", self.kae, -EDGE, EDGE),
        ] {
            super::finite(field, v)?;
            if !(lo..=hi).contains(&v) {
                let range = if lo > 0.0 {
                    format!("in (0, {hi}]")
                } else {
                    format!("in [{lo}, {hi}]")
                };
                return Err(PhysicsError::invalid(
                    field,
                    format!("{v} is not a cutting coefficient: must be {range}"),
                ));
            }
        }
        Ok(())
    }
}

/// A work material as the force model and the life model need it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "MaterialJson")]
pub struct Material {
    pub name: String,
    pub coefficients: CuttingCoefficients,
    /// Extended Taylor constants, when a source for them exists.
    pub taylor: Option<TaylorLife>,
    /// Where the numbers come from (publication, measurement campaign, identification job).
    pub source: String,
}

/// A material document: `{"name":..,"coefficients":{"ktc":..,..},"source":..,"taylor":..}`,
/// or just the six coefficients `{"ktc":..,"krc":..,"kac":..,"kte":..,"kre":..,"kae":..}`
/// (N/mm² and N/mm), for which name and source are optional.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialJson {
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    coefficients: Option<CuttingCoefficients>,
    #[serde(default)]
    taylor: Option<TaylorLife>,
    #[serde(default)]
    source: Option<String>,
    ktc: Option<f64>,
    krc: Option<f64>,
    kac: Option<f64>,
    kte: Option<f64>,
    kre: Option<f64>,
    kae: Option<f64>,
    #[serde(default)]
    mtc: f64,
    #[serde(default)]
    mrc: f64,
    #[serde(default)]
    mac: f64,
}

impl TryFrom<MaterialJson> for Material {
    type Error = String;
    fn try_from(m: MaterialJson) -> Result<Self, String> {
        let flat = [m.ktc, m.krc, m.kac, m.kte, m.kre, m.kae];
        let coefficients = match (m.coefficients, flat) {
            (Some(_), _) if m.mtc != 0.0 || m.mrc != 0.0 || m.mac != 0.0 => {
                return Err(
                    "with `coefficients`, give the exponents mtc, mrc, mac inside it".into(),
                )
            }
            (Some(c), [None, None, None, None, None, None]) => {
                return Ok(Material {
                    name: m.name.ok_or("missing field `name`")?,
                    coefficients: c,
                    taylor: m.taylor,
                    source: m.source.ok_or("missing field `source`")?,
                })
            }
            (Some(_), _) => {
                return Err(
                    "give `coefficients` or the six coefficients at the top level, not both".into(),
                )
            }
            (None, [Some(ktc), Some(krc), Some(kac), Some(kte), Some(kre), Some(kae)]) => {
                CuttingCoefficients {
                    mtc: m.mtc,
                    mrc: m.mrc,
                    mac: m.mac,
                    ..CuttingCoefficients::linear([ktc, krc, kac, kte, kre, kae])
                }
            }
            (None, flat) => {
                let names = ["ktc", "krc", "kac", "kte", "kre", "kae"];
                let missing: Vec<&str> = names
                    .iter()
                    .zip(flat)
                    .filter(|(_, v)| v.is_none())
                    .map(|(n, _)| *n)
                    .collect();
                return Err(format!(
                    "missing cutting coefficients: {} (give all six, or `coefficients`)",
                    missing.join(", ")
                ));
            }
        };
        Ok(Material {
            name: m.name.unwrap_or_else(|| "user material".into()),
            coefficients,
            taylor: m.taylor,
            source: m
                .source
                .unwrap_or_else(|| "cutting coefficients given by the user".into()),
        })
    }
}

impl Material {
    /// Checks the numbers; a user-defined material must also say where its numbers come from.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        if self.name.trim().is_empty() {
            return Err(PhysicsError::invalid("name", "must not be empty"));
        }
        if self.source.trim().is_empty() {
            return Err(PhysicsError::invalid(
                "source",
                "must say where the numbers come from",
            ));
        }
        self.coefficients.validate_range()?;
        if let Some(t) = &self.taylor {
            t.validate()?;
        }
        Ok(())
    }

    /// A built-in material by name. Matching ignores case, spaces, `-` and `_`, so
    /// "al7075-t6", "AL 7075 T6" and "Al7075T6" all find the same row.
    pub fn builtin(name: &str) -> Option<Material> {
        let key = normalize(name);
        builtin_materials()
            .into_iter()
            .find(|m| normalize(&m.name) == key)
    }
}

fn normalize(s: &str) -> String {
    s.chars()
        .filter(|c| !matches!(c, ' ' | '-' | '_'))
        .flat_map(char::to_lowercase)
        .collect()
}

/// The sourced rows of docs/reference.md, nothing else. No Taylor constants ship:
/// none of these sources gives them.
pub fn builtin_materials() -> Vec<Material> {
    let row = |name: &str, k: [f64; 6], source: &str| Material {
        name: name.to_string(),
        coefficients: CuttingCoefficients::linear(k),
        taylor: None,
        source: source.to_string(),
    };
    vec![
        row(
            "TC6",
            [1785.0, 461.0, 610.0, 26.0, 43.0, 6.0],
            "Impeller simulation and feed optimization study, Shanghai Jiao Tong University, 2019 \
             (TC6 titanium alloy, D8R1/D6R3 impeller)",
        ),
        row(
            "Al7075-T6",
            [767.01, 168.8, 222.0, 27.7, 26.6, 0.7],
            "Review, Chinese Journal of Mechanical Engineering 2021, doi:10.1186/s10033-021-00536-9, Table 5",
        ),
        row(
            "Al6082-T6",
            [631.0, 99.0, 273.0, 13.0, 10.0, 2.8],
            "Review, Chinese Journal of Mechanical Engineering 2021, doi:10.1186/s10033-021-00536-9, Table 5",
        ),
    ]
}
