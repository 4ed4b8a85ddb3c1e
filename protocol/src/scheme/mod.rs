//! Coupling schemes, one module each, holding the coordinator's side of the scheme and the
//! contract of its node side (ARCHITECTURE §5, "one place per scheme").

pub mod lagrange;
