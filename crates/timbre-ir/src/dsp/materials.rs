//! The table of materials: Young's modulus, Poisson's ratio, density and a loss factor
//! for each, shared by the physical nodes (`tube-modes` takes a material's modulus and
//! density, `impact` its modulus and Poisson's ratio).
//!
//! Every figure is a typical value of a material that varies (by alloy, species,
//! moisture, temperature, filler): a mid-range number from the sources named beside
//! it, not one measurement. The sources:
//!
//! - **Ashby**: M. F. Ashby, *Materials Selection in Mechanical Design*, 4th ed.
//!   (2011), the property ranges of chapter 4 and its data tables;
//! - **Toolbox**: The Engineering Toolbox, "Young's Modulus, Tensile Strength and Yield
//!   Strength Values for some Materials", "Poisson's Ratio" and "Densities of Solids";
//! - **FPL**: Forest Products Laboratory, *Wood Handbook*, FPL-GTR-190 (2010), tables
//!   5-3a (moduli of clear wood at 12 % moisture) and 5-1 (Poisson's ratios);
//! - **CHP**: L. Cremer, M. Heckl and B. A. T. Petersson, *Structure-Borne Sound*, 3rd
//!   ed. (2005), the table of loss factors of materials at room temperature;
//! - **HRW**: Halliday, Resnick and Walker, *Fundamentals of Physics*, Table 13-1.
//!
//! **Damping** is the loss factor η (dimensionless): the energy a vibration loses per
//! radian of its cycle over the energy it holds. A mode of frequency f made of the
//! material alone (no radiation, no losses at its supports) has the damping ratio
//! ξ = η/2, so its amplitude falls as e^(−π·η·f·t) and it decays by 60 dB in
//! T60 = 3·ln 10/(π·η·f) ≈ 2.2/(η·f) seconds.

/// A material: its elastic constants, density and internal damping, in SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub name: &'static str,
    /// Young's modulus E, Pa (along the grain, for wood).
    pub youngs: f64,
    /// Poisson's ratio ν.
    pub poisson: f64,
    /// Density ρ, kg/m³.
    pub density: f64,
    /// Loss factor η (dimensionless): see the module's notes.
    pub loss: f64,
}

impl Material {
    /// The speed of longitudinal waves in a thin bar, √(E/ρ), m/s.
    pub fn bar_speed(&self) -> f64 {
        (self.youngs / self.density).sqrt()
    }

    /// (1 − ν²)/E, this material's share of 1/E* in Hertz contact, 1/Pa.
    pub fn compliance(&self) -> f64 {
        (1.0 - self.poisson * self.poisson) / self.youngs
    }

    /// The 60 dB decay time, in seconds, of a mode of `freq` Hz damped only by this
    /// material: 3·ln 10/(π·η·f).
    pub fn t60(&self, freq: f64) -> f64 {
        3.0 * std::f64::consts::LN_10 / (std::f64::consts::PI * self.loss * freq)
    }
}

/// Steel. E, ρ: structural steel ASTM A36, 200 GPa, 7850 kg/m³ (Toolbox; HRW: 200 GPa,
/// 7860 kg/m³). ν: carbon steel 0.27–0.30 (Toolbox). η: of order 1e-4 (CHP).
pub const STEEL: Material = Material {
    name: "steel",
    youngs: 200e9,
    density: 7850.0,
    poisson: 0.29,
    loss: 1e-4,
};

/// Aluminium. E, ρ: alloy 6061-T6, 68.9 GPa, 2700 kg/m³ (Toolbox; HRW: 70 GPa,
/// 2710 kg/m³). ν: 0.33 (Toolbox). η: of order 1e-4 (CHP).
pub const ALUMINIUM: Material = Material {
    name: "aluminium",
    youngs: 69e9,
    density: 2700.0,
    poisson: 0.33,
    loss: 1e-4,
};

/// Brass. E, ρ: typical brasses 96–110 GPa, 8400–8600 kg/m³ (Toolbox; red brass
/// C83400: 101 GPa, 8740 kg/m³). ν: 0.34 (Toolbox). η: below 1e-3 (CHP: brass and
/// bronze).
pub const BRASS: Material = Material {
    name: "brass",
    youngs: 100e9,
    density: 8500.0,
    poisson: 0.34,
    loss: 1e-3,
};

/// Soda-lime glass. E: 68–72 GPa (Ashby); ρ: 2440–2490 kg/m³ (Ashby); ν: 0.22
/// (Toolbox: 0.18–0.3). η: 0.6–2e-3 (CHP).
pub const GLASS: Material = Material {
    name: "glass",
    youngs: 70e9,
    density: 2500.0,
    poisson: 0.22,
    loss: 1e-3,
};

/// A dense technical ceramic (alumina, 96 %): E 300–380 GPa, ρ 3700–3900 kg/m³, ν 0.21
/// (Ashby). η: not in CHP's table; taken as glass's, another brittle inorganic solid.
pub const CERAMIC: Material = Material {
    name: "ceramic",
    youngs: 340e9,
    density: 3800.0,
    poisson: 0.22,
    loss: 1e-3,
};

/// Oak (red or white, along the grain, 12 % moisture). E: 12.3–12.5 GPa (FPL);
/// ρ: 660–750 kg/m³ (FPL). ν: ν_LR 0.35–0.37 for oaks (FPL), used as an isotropic ν.
/// η: 0.008–0.01 (CHP: oak).
pub const OAK: Material = Material {
    name: "oak",
    youngs: 12e9,
    density: 700.0,
    poisson: 0.35,
    loss: 0.01,
};

/// Pine (eastern white pine to southern pines, along the grain, 12 % moisture).
/// E: 8.5–13.7 GPa (FPL); ρ: 370–590 kg/m³ (FPL). ν: ν_LR about 0.33 (FPL). η: taken as
/// CHP's fir, 0.008–0.01 (softwoods).
pub const PINE: Material = Material {
    name: "pine",
    youngs: 9e9,
    density: 500.0,
    poisson: 0.33,
    loss: 0.008,
};

/// Plastic: acrylic (PMMA). E: 2.2–3.8 GPa, ρ: 1170–1200 kg/m³, ν: 0.35–0.40 (Ashby).
/// η: 0.02–0.04 (CHP: Plexiglas).
pub const PLASTIC: Material = Material {
    name: "plastic",
    youngs: 3e9,
    density: 1180.0,
    poisson: 0.37,
    loss: 0.03,
};

/// Rubber: vulcanised natural rubber, small strains. E: 1.5–5 MPa (Ashby: elastomers
/// 1–10 MPa); ρ: 920–1300 kg/m³ (Ashby, filled or not); ν: 0.49, nearly incompressible
/// (Toolbox: 0.48–0.5). η: 0.1–1 (CHP), the lower end for a soft compound.
pub const RUBBER: Material = Material {
    name: "rubber",
    youngs: 5e6,
    density: 1100.0,
    poisson: 0.49,
    loss: 0.1,
};

/// Stone: granite. E: 50–70 GPa (Toolbox: 52 GPa; Ashby: 62–70 GPa for granite);
/// ρ: 2600–2800 kg/m³ (Toolbox); ν: 0.25 (Toolbox: 0.2–0.3). η: not in CHP's table;
/// taken at heavy concrete's lower end, 0.005 (a rigid, lightly cracked solid).
pub const STONE: Material = Material {
    name: "stone",
    youngs: 60e9,
    density: 2700.0,
    poisson: 0.25,
    loss: 0.005,
};

/// Concrete (normal weight). E: 25–40 GPa (Toolbox: 30 GPa); ρ: 2300–2400 kg/m³
/// (Toolbox); ν: 0.2 (Toolbox: 0.1–0.2). η: 4–8e-3 for heavy concrete (CHP).
pub const CONCRETE: Material = Material {
    name: "concrete",
    youngs: 30e9,
    density: 2400.0,
    poisson: 0.2,
    loss: 0.006,
};

/// Bamboo along the culm. A natural composite: its stiffness and density vary with
/// species, age, moisture and the position in the culm wall, by a factor of two or
/// so; these are mid-range values, not one measurement. ν and η are taken as a
/// softwood's (pine's), for want of a handbook figure.
pub const BAMBOO: Material = Material {
    name: "bamboo",
    youngs: 18e9,
    density: 700.0,
    poisson: 0.33,
    loss: 0.008,
};

/// Every material, in the order of the table in `lang-spec/nodes.md`.
pub const MATERIALS: [Material; 12] = [
    STEEL, ALUMINIUM, BRASS, GLASS, CERAMIC, OAK, PINE, PLASTIC, RUBBER, STONE, CONCRETE, BAMBOO,
];

/// The material called `name`, if the table has it.
pub fn material(name: &str) -> Option<&'static Material> {
    MATERIALS.iter().find(|m| m.name == name)
}

/// The names of the table's materials, in its order.
pub fn names() -> impl Iterator<Item = &'static str> {
    MATERIALS.iter().map(|m| m.name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_material_is_positive_finite_and_named_once() {
        for (k, m) in MATERIALS.iter().enumerate() {
            for x in [m.youngs, m.density, m.loss] {
                assert!(x.is_finite() && x > 0.0, "{}", m.name);
            }
            // Stable isotropic solids have −1 < ν < 1/2.
            assert!(m.poisson > -1.0 && m.poisson < 0.5, "{}", m.name);
            assert_eq!(material(m.name), Some(&MATERIALS[k]));
        }
        assert_eq!(material("wood"), None);
    }

    #[test]
    fn the_bar_speeds_and_t60s_are_the_textbook_ones() {
        // √(E/ρ), m/s: steel 5048, glass 5292, oak 4140, rubber 67.
        let speed = |name| material(name).map(|m| m.bar_speed().round());
        assert_eq!(speed("steel"), Some(5048.0));
        assert_eq!(speed("glass"), Some(5292.0));
        assert_eq!(speed("oak"), Some(4140.0));
        assert_eq!(speed("rubber"), Some(67.0));
        // η = 0.01 at 1 kHz: 6.9078/(π·0.01·1000) = 0.21988 s.
        assert!((OAK.t60(1000.0) - 0.219_881).abs() < 1e-6);
    }
}
