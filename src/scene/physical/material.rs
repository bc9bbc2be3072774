//! A physical object's material: a table entry by name with the scene's
//! overrides, resolved to the values the shapes take.

use crate::bodies::materials::{self, Material};
use crate::scene::error::{check_finite, SceneError};
use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};
use std::fmt;

/// Values of a material: a table entry by `name`, any value overridden.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Entry of the material table (`steel`, `rosewood`, ...); may be
    /// omitted when every value the kind needs is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Density \[kg/m^3\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density_kg_per_m3: Option<f64>,
    /// Young's modulus \[Pa\] (woods: along the grain).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub youngs_modulus_pa: Option<f64>,
    /// Shear modulus \[Pa\] (Timoshenko correction, torsion).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear_modulus_pa: Option<f64>,
    /// Poisson's ratio, in (-1, 0.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poisson_ratio: Option<f64>,
    /// Material loss factor `eta` (`sigma = eta omega / 2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss_factor: Option<f64>,
}

/// `material = "steel"` is short for `material = { name = "steel" }`.
pub(super) fn material_spec<'de, D: Deserializer<'de>>(d: D) -> Result<MaterialSpec, D::Error> {
    struct V;
    impl<'de> Visitor<'de> for V {
        type Value = MaterialSpec;
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("a material name or a table of material values")
        }
        fn visit_str<E: de::Error>(self, s: &str) -> Result<MaterialSpec, E> {
            Ok(MaterialSpec {
                name: Some(s.to_string()),
                ..MaterialSpec::default()
            })
        }
        fn visit_map<M: MapAccess<'de>>(self, m: M) -> Result<MaterialSpec, M::Error> {
            MaterialSpec::deserialize(de::value::MapAccessDeserializer::new(m))
        }
    }
    d.deserialize_any(V)
}

pub(super) fn optional_material_spec<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<MaterialSpec>, D::Error> {
    material_spec(d).map(Some)
}

impl MaterialSpec {
    /// The table entry with the overrides applied; each needed value must
    /// come from one of them.
    pub(super) fn resolve(&self, base: &str) -> Result<Material, SceneError> {
        let mut m = match &self.name {
            Some(n) => materials::material(n)
                .map_err(|e| SceneError::new(format!("{base}.material.name"), e))?,
            None => Material {
                name: "custom",
                description: "values given in the scene",
                density_kg_m3: f64::NAN,
                youngs_modulus_pa: f64::NAN,
                shear_modulus_pa: f64::NAN,
                poisson_ratio: 0.3,
                loss_factor: 0.0,
            },
        };
        let fields = [
            (
                &mut m.density_kg_m3,
                self.density_kg_per_m3,
                "density_kg_per_m3",
            ),
            (
                &mut m.youngs_modulus_pa,
                self.youngs_modulus_pa,
                "youngs_modulus_pa",
            ),
            (
                &mut m.shear_modulus_pa,
                self.shear_modulus_pa,
                "shear_modulus_pa",
            ),
            (&mut m.poisson_ratio, self.poisson_ratio, "poisson_ratio"),
            (&mut m.loss_factor, self.loss_factor, "loss_factor"),
        ];
        for (slot, given, field) in fields {
            if let Some(v) = given {
                check_finite(&format!("{base}.material.{field}"), v)?;
                *slot = v;
            }
        }
        if self.name.is_none() {
            for (v, field) in [
                (m.density_kg_m3, "density_kg_per_m3"),
                (m.youngs_modulus_pa, "youngs_modulus_pa"),
            ] {
                if v.is_nan() {
                    return Err(SceneError::new(
                        format!("{base}.material"),
                        format!("needs a table `name` or `{field}`"),
                    ));
                }
            }
            if m.shear_modulus_pa.is_nan() {
                // isotropic: G = E / (2 (1 + nu))
                m.shear_modulus_pa = m.youngs_modulus_pa / (2.0 * (1.0 + m.poisson_ratio));
            }
        }
        m.validate().map_err(|e| {
            let reason = e
                .split_once(": ")
                .map_or(e.as_str(), |(_, r)| r)
                .to_string();
            let field = reason
                .split_once(':')
                .map_or("", |(f, _)| f)
                .replace("density_kg_m3", "density_kg_per_m3");
            let reason = reason.split_once(": ").map_or(reason.as_str(), |(_, r)| r);
            SceneError::new(format!("{base}.material.{field}"), reason.to_string())
        })?;
        Ok(m)
    }
}
