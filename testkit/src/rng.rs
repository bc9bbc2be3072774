//! The seeded generator of every test, benchmark and plugin test.
//!
//! The implementation lives in the plugin library (hidden) so that the unit
//! tests inside it can use it too; this is the one name everything outside
//! the library uses.

pub use modal_contact::test_rng::TestRng;
