//! Vibrating bodies from geometry and material: the modes of bars, tubes,
//! plates, membranes and stiff strings ([`shapes`]), a table of materials
//! ([`materials`]), the free lumped chain of a mallet ([`chain`]) and the
//! surface profiles of a driven contact ([`surface`]). Pure functions of plain numbers; nothing here
//! knows about scenes or the engine (docs/design.md, "Objects from geometry
//! and material").

pub mod chain;
pub mod materials;
pub mod radiated_power;
pub mod radiation;
pub mod resonator;
pub mod shapes;
pub mod surface;
