//! A small table of common instrument materials for [`crate::bodies::shapes`]:
//! density, Young's modulus, shear modulus, Poisson's ratio and a loss factor.
//!
//! Every value carries its source in a comment. Natural materials vary a lot
//! (wood by +-20 % between boards of one species), so the table gives typical
//! values, not specifications: look one up with [`material`], then override
//! any field of the returned plain struct with measured values.
//!
//! - Woods are orthotropic. `youngs_modulus_pa` is the **longitudinal**
//!   modulus `E_L` (along the grain, the axis of a bar cut along the grain);
//!   `shear_modulus_pa` is `G_LR` (the shear that matters for a bar bending
//!   across its thickness with the growth rings parallel to the width);
//!   `poisson_ratio` is `nu_LR`. A plate of wood is *not* isotropic: the
//!   isotropic plate formulas with these values are a crude approximation.
//! - Wood Handbook moduli come from static bending tests, which include shear
//!   deflection; the Handbook (FPL-GTR-190, ch. 5, "Modulus of elasticity")
//!   says to raise them by 10 % to remove it. The values below are raised,
//!   so they are pure bending moduli (shear enters separately, through the
//!   Timoshenko correction of `shapes`).
//! - Densities of woods are at 12 % moisture content:
//!   `rho = SG_12 * (1 + 0.12) * 1000 kg/m^3`, with `SG_12` the Handbook's
//!   specific gravity (oven-dry weight over volume at 12 % MC).
//! - Loss factors `eta` (`sigma = eta omega / 2`, `T60 = 2 ln(1000) / (eta
//!   omega)`) are material (internal) damping only; radiation and supports
//!   add to it (see `shapes::LossModel`). Metals' loss factors are
//!   orders of magnitude and depend strongly on alloy, temper and amplitude.
//!
//! Sources (short names used in the comments):
//! - \[WH\]: Forest Products Laboratory, *Wood Handbook: Wood as an Engineering
//!   Material*, USDA FPL-GTR-190 (2010), Tables 5-1 (elastic ratios), 5-2
//!   (Poisson's ratios), 5-3a (properties of US hardwoods and softwoods).
//! - \[Bre12\]: I. Bremaud, "Acoustical properties of wood in string instruments
//!   soundboards and tuned idiophones: biological and cultural diversity",
//!   JASA 131(1), 807-818 (2012), and Bremaud et al., "Anisotropy of wood
//!   vibrational properties" (Wood Sci. Technol. 2011): `E_L` of Dalbergia
//!   stevensonii 17-26 GPa, lowest `tan delta` of the idiophone woods.
//! - \[ATIBT\]: ATIBT (1990), *Atlas de maderas tropicales de America Latina*:
//!   Honduras rosewood 900-1050 kg/m^3 at 12 % MC.
//! - \[WDB\]: E. Meier, *The Wood Database* (wood-database.com), species pages.
//! - \[BrB10\]: L. Brancheriau et al., "Acoustic quality of vene wood
//!   (Pterocarpus erinaceus) for xylophone manufacture in Mali", Ann. For. Sci.
//!   67, 815 (2010): `tan delta` of Pterocarpus xylophone wood ~ 0.006-0.009.
//! - \[CH\]: L. Cremer, M. Heckl, B. A. T. Petersson, *Structure-Borne Sound*,
//!   3rd ed., Springer (2005), table of loss factors of materials (aluminium
//!   ~1e-4; steel 1e-4..6e-4; brass <1e-3; glass 6e-4..2e-3; plexiglass
//!   2e-2..4e-2; wood (oak, fir) 8e-3..1e-2).
//! - \[MW\]: MatWeb material datasheets (matweb.com): "Aluminum 6061-T6",
//!   "AISI 1018 Steel, cold drawn", "Copper C26000 (cartridge brass)",
//!   "Soda-lime glass", "ABS, molded" and "Acrylic (PMMA)" overviews,
//!   "Nylon 66, dry as molded" overview.
//! - \[CDA\]: Copper Development Association data for cast tin bronzes:
//!   C91300 (bell metal, 79-82 Cu, 18-20 Sn) density 0.318 lb/in^3
//!   (8.80 g/cm^3); C91100 (16 Sn) modulus 15,000 ksi (103 GPa).
//! - \[FR\]: N. H. Fletcher, T. D. Rossing, *The Physics of Musical
//!   Instruments*, 2nd ed., Springer (1998).
//!
//! Values marked *(estimate)* have no direct tabulated source in the list
//! above and are an informed choice inside the stated range: override them
//! when measured values are at hand.

/// Mechanical properties of one material (SI units). Plain data: copy it
/// from the table with [`material`] and override any field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Table name (lower case, `_` between words).
    pub name: &'static str,
    /// What the entry is (species, alloy, grain direction).
    pub description: &'static str,
    /// Density `rho` \[kg/m^3\].
    pub density_kg_m3: f64,
    /// Young's modulus `E` \[Pa\] (woods: along the grain, `E_L`).
    pub youngs_modulus_pa: f64,
    /// Shear modulus `G` \[Pa\] (woods: `G_LR`).
    pub shear_modulus_pa: f64,
    /// Poisson's ratio `nu` (woods: `nu_LR`).
    pub poisson_ratio: f64,
    /// Material loss factor `eta` (`sigma = eta omega / 2`).
    pub loss_factor: f64,
}

impl Material {
    /// Check every field: densities and moduli finite and `> 0`, `-1 < nu <
    /// 0.5`, `0 <= eta < 1`. Errors name the field.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.name;
        for (field, v) in [
            ("density_kg_m3", self.density_kg_m3),
            ("youngs_modulus_pa", self.youngs_modulus_pa),
            ("shear_modulus_pa", self.shear_modulus_pa),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "material {n}: {field}: must be finite and > 0, got {v}"
                ));
            }
        }
        let nu = self.poisson_ratio;
        if !(nu > -1.0 && nu < 0.5) {
            return Err(format!(
                "material {n}: poisson_ratio: must be in (-1, 0.5), got {nu}"
            ));
        }
        let eta = self.loss_factor;
        if !(0.0..1.0).contains(&eta) {
            return Err(format!(
                "material {n}: loss_factor: must be in [0, 1), got {eta}"
            ));
        }
        Ok(())
    }

    /// `E / rho` \[m^2/s^2\]: the square of the longitudinal bar wave speed.
    pub fn specific_modulus(&self) -> f64 {
        self.youngs_modulus_pa / self.density_kg_m3
    }
}

/// Density at 12 % moisture content from the Wood Handbook's specific
/// gravity (oven-dry weight, volume at 12 % MC).
const fn wood_density(sg12: f64) -> f64 {
    sg12 * 1.12 * 1000.0
}

/// The material table. Names are lower case; [`material`] also accepts the
/// aliases listed there.
pub const MATERIALS: &[Material] = &[
    Material {
        name: "rosewood",
        description: "Honduras rosewood (Dalbergia stevensonii), the marimba wood; \
                      along the grain",
        // [ATIBT]: 900-1050 kg/m^3 at 12 % MC; mid-range.
        density_kg_m3: 1000.0,
        // [Bre12]: E_L 17-26 GPa for D. stevensonii; mid-range.
        youngs_modulus_pa: 20.0e9,
        // (estimate) G_LR / E_L = 0.07, inside the hardwood range 0.05-0.12
        // of [WH] Table 5-1; no measured G_LR found for this species.
        shear_modulus_pa: 0.07 * 20.0e9,
        // (estimate) nu_LR of hardwoods in [WH] Table 5-2 spans 0.29-0.49;
        // 0.37 typical of dense hardwoods.
        poisson_ratio: 0.37,
        // [Bre12]: tan delta ~ 0.004-0.006, lowest of the idiophone woods.
        loss_factor: 0.005,
    },
    Material {
        name: "padauk",
        description: "African padauk (Pterocarpus soyauxii), xylophone wood; along the grain",
        // [WDB] African padauk: average dried weight 745 kg/m^3 (12 % MC).
        density_kg_m3: 745.0,
        // [WDB] African padauk: elastic modulus 11.72 GPa (static bending),
        // +10 % shear correction as for [WH] values.
        youngs_modulus_pa: 1.10 * 11.72e9,
        // (estimate) G_LR / E_L = 0.07 as for rosewood ([WH] Table 5-1 range).
        shear_modulus_pa: 0.07 * 1.10 * 11.72e9,
        // (estimate) typical hardwood nu_LR, [WH] Table 5-2 range 0.29-0.49.
        poisson_ratio: 0.37,
        // [BrB10]: Pterocarpus xylophone wood tan delta ~ 0.006-0.009.
        loss_factor: 0.007,
    },
    Material {
        name: "maple",
        description: "sugar (hard) maple (Acer saccharum); along the grain",
        // [WH] Table 5-3a: SG 0.63 at 12 % MC -> 706 kg/m^3.
        density_kg_m3: wood_density(0.63),
        // [WH] Table 5-3a: MOE 12.6 GPa at 12 % MC, +10 % shear correction.
        youngs_modulus_pa: 1.10 * 12.6e9,
        // [WH] Table 5-1, sugar maple: G_LR / E_L = 0.111.
        shear_modulus_pa: 0.111 * 1.10 * 12.6e9,
        // [WH] Table 5-2, sugar maple: mu_LR = 0.424.
        poisson_ratio: 0.424,
        // [CH]: wood 8e-3..1e-2; lower end.
        loss_factor: 0.008,
    },
    Material {
        name: "spruce",
        description: "Sitka spruce (Picea sitchensis), soundboard wood; along the grain",
        // [WH] Table 5-3a: SG 0.40 at 12 % MC -> 448 kg/m^3.
        density_kg_m3: wood_density(0.40),
        // [WH] Table 5-3a: MOE 10.8 GPa at 12 % MC, +10 % shear correction.
        youngs_modulus_pa: 1.10 * 10.8e9,
        // [WH] Table 5-1, Sitka spruce: G_LR / E_L = 0.064.
        shear_modulus_pa: 0.064 * 1.10 * 10.8e9,
        // [WH] Table 5-2, Sitka spruce: mu_LR = 0.372.
        poisson_ratio: 0.372,
        // [CH]: wood (fir) 8e-3..1e-2; spruce soundwood is at the low end.
        loss_factor: 0.008,
    },
    Material {
        name: "aluminium",
        description: "aluminium alloy 6061-T6 (chimes, bars)",
        // [MW] Aluminum 6061-T6: density 2.70 g/cm^3.
        density_kg_m3: 2700.0,
        // [MW] Aluminum 6061-T6: modulus of elasticity 68.9 GPa.
        youngs_modulus_pa: 68.9e9,
        // [MW] Aluminum 6061-T6: shear modulus 26.0 GPa.
        shear_modulus_pa: 26.0e9,
        // [MW] Aluminum 6061-T6: Poisson's ratio 0.33.
        poisson_ratio: 0.33,
        // [CH]: aluminium ~1e-4.
        loss_factor: 1.0e-4,
    },
    Material {
        name: "steel",
        description: "plain carbon steel (AISI 1018, cold drawn)",
        // [MW] AISI 1018: density 7.87 g/cm^3.
        density_kg_m3: 7870.0,
        // [MW] AISI 1018: modulus of elasticity 205 GPa.
        youngs_modulus_pa: 205.0e9,
        // [MW] AISI 1018: shear modulus 80.0 GPa.
        shear_modulus_pa: 80.0e9,
        // [MW] AISI 1018: Poisson's ratio 0.29.
        poisson_ratio: 0.29,
        // [CH]: steel 1e-4..6e-4; lower part of the range.
        loss_factor: 2.0e-4,
    },
    Material {
        name: "brass",
        description: "cartridge brass C26000 (70 Cu / 30 Zn)",
        // [MW] C26000: density 8.53 g/cm^3.
        density_kg_m3: 8530.0,
        // [MW] C26000: modulus of elasticity 110 GPa.
        youngs_modulus_pa: 110.0e9,
        // [MW] C26000: shear modulus 40 GPa.
        shear_modulus_pa: 40.0e9,
        // [MW] C26000: Poisson's ratio 0.375.
        poisson_ratio: 0.375,
        // [CH]: brass < 1e-3.
        loss_factor: 1.0e-3,
    },
    Material {
        name: "bell_bronze",
        description: "bell metal, high-tin bronze (about 80 Cu / 20 Sn, UNS C91300)",
        // [CDA] C91300: 0.318 lb/in^3 = 8.80 g/cm^3.
        density_kg_m3: 8800.0,
        // [CDA] C91100 (16 % Sn): 15,000 ksi = 103 GPa; taken for C91300.
        youngs_modulus_pa: 103.0e9,
        // Isotropic relation G = E / (2 (1 + nu)) with the values here.
        shear_modulus_pa: 103.0e9 / (2.0 * 1.34),
        // (estimate) 0.34, the usual value for cast bronzes (ASM Handbook
        // vol. 2 typical for copper-tin alloys).
        poisson_ratio: 0.34,
        // (estimate) between steel and brass of [CH]; bells ring for tens of
        // seconds ([FR] ch. 21), i.e. eta of order 1e-4..1e-3.
        loss_factor: 3.0e-4,
    },
    Material {
        name: "glass",
        description: "soda-lime glass",
        // [MW] soda-lime glass: density 2.44-2.52 g/cm^3; 2.50 typical.
        density_kg_m3: 2500.0,
        // [MW] soda-lime glass: modulus of elasticity 72 GPa (69-74).
        youngs_modulus_pa: 72.0e9,
        // [MW] soda-lime glass: shear modulus 29.5 GPa.
        shear_modulus_pa: 29.5e9,
        // [MW] soda-lime glass: Poisson's ratio 0.22.
        poisson_ratio: 0.22,
        // [CH]: glass 6e-4..2e-3.
        loss_factor: 1.0e-3,
    },
    Material {
        name: "abs",
        description: "ABS (acrylonitrile butadiene styrene), molded",
        // [MW] ABS, molded: density 1.03-1.06 g/cm^3.
        density_kg_m3: 1050.0,
        // [MW] ABS, molded: tensile modulus ~2.3 GPa (1.8-2.9).
        youngs_modulus_pa: 2.3e9,
        // Isotropic relation G = E / (2 (1 + nu)).
        shear_modulus_pa: 2.3e9 / (2.0 * 1.35),
        // [MW] ABS: Poisson's ratio ~0.35.
        poisson_ratio: 0.35,
        // (estimate) glassy amorphous polymer at room temperature, audio
        // frequencies: of the order of [CH]'s plexiglass value, 1e-2..4e-2.
        loss_factor: 0.02,
    },
    Material {
        name: "acrylic",
        description: "acrylic, PMMA (cast sheet)",
        // [MW] acrylic: density 1.17-1.20 g/cm^3.
        density_kg_m3: 1190.0,
        // [MW] acrylic: modulus of elasticity ~3.1 GPa (2.2-3.8).
        youngs_modulus_pa: 3.1e9,
        // Isotropic relation G = E / (2 (1 + nu)).
        shear_modulus_pa: 3.1e9 / (2.0 * 1.37),
        // [MW] acrylic: Poisson's ratio 0.35-0.40; 0.37.
        poisson_ratio: 0.37,
        // [CH]: plexiglass 2e-2..4e-2.
        loss_factor: 0.03,
    },
    Material {
        name: "nylon",
        description: "nylon 66 (polyamide 6/6), dry as molded",
        // [MW] nylon 66, dry as molded: density 1.14 g/cm^3.
        density_kg_m3: 1140.0,
        // [MW] nylon 66, dry as molded: modulus ~2.9 GPa (moisture lowers
        // it substantially).
        youngs_modulus_pa: 2.9e9,
        // Isotropic relation G = E / (2 (1 + nu)).
        shear_modulus_pa: 2.9e9 / (2.0 * 1.39),
        // [MW] nylon 66: Poisson's ratio ~0.39.
        poisson_ratio: 0.39,
        // (estimate) semicrystalline polymer, of the order of [CH]'s
        // plexiglass value.
        loss_factor: 0.03,
    },
];

/// Look a material up by name, case-insensitively; spaces and `-` count as
/// `_`. Aliases: `aluminum`, `al6061` -> `aluminium`; `honduras_rosewood`
/// -> `rosewood`; `african_padauk` -> `padauk`; `hard_maple`,
/// `sugar_maple` -> `maple`; `sitka_spruce` -> `spruce`; `bronze`,
/// `bell_metal` -> `bell_bronze`; `pmma`, `plexiglass` -> `acrylic`;
/// `nylon66` -> `nylon`.
pub fn material(name: &str) -> Result<Material, String> {
    let key: String = name
        .trim()
        .chars()
        .map(|c| match c {
            ' ' | '-' => '_',
            c => c.to_ascii_lowercase(),
        })
        .collect();
    let canonical = match key.as_str() {
        "aluminum" | "al6061" | "aluminium_6061" | "aluminum_6061" => "aluminium",
        "honduras_rosewood" => "rosewood",
        "african_padauk" => "padauk",
        "hard_maple" | "sugar_maple" => "maple",
        "sitka_spruce" => "spruce",
        "bronze" | "bell_metal" => "bell_bronze",
        "pmma" | "plexiglass" | "plexiglas" => "acrylic",
        "nylon66" | "nylon_66" => "nylon",
        k => k,
    };
    MATERIALS
        .iter()
        .find(|m| m.name == canonical)
        .copied()
        .ok_or_else(|| {
            let names: Vec<&str> = MATERIALS.iter().map(|m| m.name).collect();
            format!(
                "material: unknown name {name:?}; known: {}",
                names.join(", ")
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_entry_validates_and_names_are_unique() {
        for (i, m) in MATERIALS.iter().enumerate() {
            m.validate().unwrap();
            assert!(
                MATERIALS[i + 1..].iter().all(|o| o.name != m.name),
                "duplicate {}",
                m.name
            );
            assert_eq!(material(m.name).unwrap(), *m);
        }
    }

    #[test]
    fn lookup_aliases_case_and_unknown_names() {
        assert_eq!(material("Aluminum").unwrap().name, "aluminium");
        assert_eq!(material("  Honduras Rosewood ").unwrap().name, "rosewood");
        assert_eq!(material("bell-metal").unwrap().name, "bell_bronze");
        assert_eq!(material("PMMA").unwrap().name, "acrylic");
        let err = material("unobtainium").unwrap_err();
        assert!(
            err.contains("unobtainium") && err.contains("rosewood"),
            "{err}"
        );
    }

    #[test]
    fn isotropic_entries_satisfy_g_from_e_and_nu() {
        // Datasheet G, E and nu of an isotropic solid must agree with
        // G = E / (2 (1 + nu)): a check against typing errors in the table.
        for name in [
            "aluminium",
            "steel",
            "brass",
            "bell_bronze",
            "glass",
            "abs",
            "acrylic",
            "nylon",
        ] {
            let m = material(name).unwrap();
            let g = m.youngs_modulus_pa / (2.0 * (1.0 + m.poisson_ratio));
            let rel = m.shear_modulus_pa / g - 1.0;
            println!("{name}: G table / G(E, nu) - 1 = {rel:+.4}");
            assert!(rel.abs() < 0.05, "{name}: {rel}");
        }
        // Woods are strongly anisotropic: G_LR far below E_L / 2.6.
        for name in ["rosewood", "padauk", "maple", "spruce"] {
            let m = material(name).unwrap();
            assert!(m.shear_modulus_pa < 0.15 * m.youngs_modulus_pa, "{name}");
        }
    }

    #[test]
    fn wave_speeds_are_in_the_textbook_ranges() {
        // Longitudinal bar speed sqrt(E / rho) [m/s]: aluminium ~5100, steel
        // ~5100, brass ~3600, glass ~5400, spruce along the grain ~5000,
        // PMMA ~1600 ([FR] appendix tables give the same orders).
        for (name, lo, hi) in [
            ("aluminium", 4900.0, 5300.0),
            ("steel", 4900.0, 5300.0),
            ("brass", 3400.0, 3800.0),
            ("glass", 5100.0, 5600.0),
            ("spruce", 4500.0, 5600.0),
            ("rosewood", 4000.0, 5400.0),
            ("acrylic", 1400.0, 1800.0),
        ] {
            let c = material(name).unwrap().specific_modulus().sqrt();
            println!("{name}: c = {c:.0} m/s");
            assert!(c > lo && c < hi, "{name}: {c}");
        }
    }

    #[test]
    fn overrides_are_plain_field_writes_and_are_validated() {
        let mut m = material("maple").unwrap();
        m.youngs_modulus_pa = 13.0e9;
        m.validate().unwrap();
        m.poisson_ratio = 0.6;
        let err = m.validate().unwrap_err();
        assert!(err.contains("poisson_ratio"), "{err}");
        m.poisson_ratio = 0.3;
        m.density_kg_m3 = f64::NAN;
        let err = m.validate().unwrap_err();
        assert!(err.contains("density_kg_m3"), "{err}");
    }
}
