//! Multisample export (to be written).
