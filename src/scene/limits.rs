//! The ranges of a scene's values: the file layout version, the sizes of
//! its objects and contacts, and the bounds of every physical number, each
//! with its reason. `validate.rs` refuses a value outside its range,
//! naming the field.

/// The only scene file layout version this build reads.
pub const SCENE_VERSION: u32 = 1;
/// Largest number of lumped masses in a `kind = "string"` object. The contact
/// system has `2 * masses + 2` states and is diagonalised off the audio thread;
/// 2000 masses already take seconds (docs/numerics.md, "Decomposing a phase").
pub const MAX_STRING_MASSES: usize = 2000;
/// Largest number of modes in one modal object (same reason as above).
pub const MAX_MODES_PER_OBJECT: usize = 4000;
/// Frequencies above this are refused as nonsense (10 MHz is far above any
/// audio rate this plugin runs at; above-Nyquist modes below it are legal).
pub const MAX_FREQ_HZ: f64 = 1.0e7;

// Ranges of the other physical values. Outside them the compiled matrices
// overflow or lose all precision (tests/fuzz_scenes.rs found each case: a
// 1e-300 kg hammer or a 5e-324 s T60 gives non-finite generators, gravity
// 1e300 non-finite energies, a gain of 1e300 non-finite output), so a scene
// file is refused with the field's name instead. Each range is far wider than
// any instrument needs.

/// Lowest mode frequency \[Hz\]: a period of 1000 s, longer than any render; a
/// 0 Hz mode would be a free rigid body, which is not a mode.
pub const MIN_FREQ_HZ: f64 = 1.0e-3;
/// Shortest T60 \[s\]: 60 dB of decay in a microsecond (damping rate
/// `ln(1000) / T60` up to 6.9e6 1/s) is far beyond any audible damping.
pub const MIN_T60_S: f64 = 1.0e-6;
/// Largest mode weight magnitude \[1/sqrt(kg)\]: a mode that looks like a mass
/// of `1 / w^2 = 1e-12` kg at that point ([`MIN_MASS_KG`]).
pub const MAX_WEIGHT: f64 = 1.0e6;
/// Lightest and heaviest mass \[kg\] (hammer, string masses): the lower limit
/// is the effective mass of the largest allowed weight, `1 / MAX_WEIGHT^2`.
pub const MIN_MASS_KG: f64 = 1.0e-12;
/// See [`MIN_MASS_KG`] (a thousand tonnes).
pub const MAX_MASS_KG: f64 = 1.0e6;
/// Smallest contact stiffness \[N/m\]: a spring that pushes with 1 uN per mm
/// of compression. Softer ones overflow the static equilibrium under
/// gravity (`m g / k`; tests/fuzz_scenes.rs found `5e-324`).
pub const MIN_STIFFNESS_N_PER_M: f64 = 1.0e-3;
/// Largest contact or string spring stiffness \[N/m\] (a contact frequency of
/// 1000x the Nyquist frequency of 44.1 kHz with a 20 g hammer needs 3.8e14).
pub const MAX_STIFFNESS_N_PER_M: f64 = 1.0e16;
/// Largest contact or dashpot damping \[N s/m\] (an overdamped contact with
/// zeta = 1e3 for a 20 g hammer on 1e6 N/m needs 2.8e5).
pub const MAX_DAMPING_N_S_PER_M: f64 = 1.0e9;
/// Largest Rayleigh mass-proportional damping \[1/s\] (the rate of a T60 of
/// [`MIN_T60_S`]: `2 ln(1000) / 1e-6`).
pub const MAX_RAYLEIGH_ALPHA_PER_S: f64 = 1.4e7;
/// Largest Rayleigh stiffness-proportional damping \[s\] (1 s damps every
/// mode above 1 Hz critically).
pub const MAX_RAYLEIGH_BETA_S: f64 = 1.0;
/// Largest hammer height \[m\] and speed \[m/s\] (three times the speed of
/// sound in air).
pub const MAX_HEIGHT_M: f64 = 1.0e3;
/// See [`MAX_HEIGHT_M`].
pub const MAX_SPEED_M_PER_S: f64 = 1.0e3;
/// Largest gravity \[m/s^2\] (a thousand g).
pub const MAX_GRAVITY_M_PER_S2: f64 = 1.0e4;
/// Largest pickup gain magnitude (+120 dB).
pub const MAX_GAIN: f64 = 1.0e6;
/// Longest `duration_s` \[s\] (the renderer's limit).
pub const MAX_DURATION_S: f64 = 3600.0;
/// Quietest and loudest `level_db` \[dB\], the output level a scene states
/// (docs/design.md, "Scene files"): far wider than the spread of the
/// presets' loudness, which it evens out.
pub const MIN_LEVEL_DB: f64 = -60.0;
/// See [`MIN_LEVEL_DB`].
pub const MAX_LEVEL_DB: f64 = 40.0;

/// Most contacts of one scene: `[contact]` and up to `MAX_CONTACTS - 1`
/// strikers and touches.
pub const MAX_CONTACTS: usize = 4;

/// Most springs of one scene once every law is springs side by side (a
/// contact without a law one, with a law one per piece: docs/design.md,
/// "Stiffening contacts"); the several-contact engine's contacts.
pub const MAX_SPRINGS: usize = 12;

/// Farthest listener \[m\].
pub const MAX_LISTENER_DISTANCE_M: f64 = 1000.0;
/// Nearest listener \[m\] (closer is not the far field of any object;
/// it also keeps the pressure pickups' gains within [`MAX_GAIN`]).
pub const MIN_LISTENER_DISTANCE_M: f64 = 0.1;
