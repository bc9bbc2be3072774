//! Vibrating bodies from geometry and material: the modes of bars, tubes,
//! plates, membranes and stiff strings ([`shapes`]) and a table of
//! materials ([`materials`]). Pure functions of plain numbers; nothing here
//! knows about scenes or the engine (docs/design.md, "Objects from geometry
//! and material").

pub mod materials;
pub mod shapes;
