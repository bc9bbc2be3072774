//! Time scale (pitch), pitch bend and output band: the one-sample
//! propagators and output rows a voice derives from its scene at a time
//! scale, computed on the audio thread or made ahead ([`ScaleProps`]).

use super::kernel::BlockProps;
use super::{BandRows, EngineState, ScaleProps, TimeScaleError, CONTACT, FREE};
use crate::compile::{CompiledPhase, CompiledScene};
use crate::physics::block::exp2;

impl EngineState {
    /// Current time scale.
    pub fn time_scale(&self) -> f64 {
        self.time_scale
    }

    /// Run the scene with its time axis scaled by `s` (pitch ratio). O(N), no
    /// allocation (plus O(N M) for M modes left out by the output band, see
    /// [`EngineState::set_output_band`]). \[audio-thread\]
    pub fn set_time_scale(&mut self, scene: &CompiledScene, s: f64) -> Result<(), TimeScaleError> {
        scale_allowed(scene, s)?;
        self.settle(scene);
        self.set_time_scale_inner(scene, s);
        Ok(())
    }

    /// Change the time scale to `s` as a pitch bend does, without adding or
    /// removing energy: the object's state is scaled by `s_old / s` (its
    /// energy in reference units by `(s_old / s)^2`, so the physical energy
    /// `s^2 E_ref` is unchanged: a higher pitch at the same energy is a
    /// smaller displacement) and the hammer in flight keeps its physical
    /// velocity. Nothing happens in contact (the spring, the hammer and the
    /// object are coupled there): returns `Ok(false)` and the caller tries
    /// again after the release. In a scene with gravity the hammer's
    /// potential energy would change with the time axis: refused like
    /// the dense fallback ([`TimeScaleError::Gravity`]). O(N),
    /// allocation-free. \[audio-thread\]
    pub fn bend_time_scale(
        &mut self,
        scene: &CompiledScene,
        s: f64,
    ) -> Result<bool, TimeScaleError> {
        if !(s.is_finite() && s > 0.0) {
            return Err(TimeScaleError::Invalid);
        }
        if scene.free.dense.is_some() || scene.contact.dense.is_some() {
            return Err(TimeScaleError::DenseFallback);
        }
        if scene.g != 0.0 {
            return Err(TimeScaleError::Gravity);
        }
        // (a replaying voice in contact waits like any other, unsettled)
        if self.in_contact() {
            return Ok(false);
        }
        self.settle(scene);
        if self.in_contact() {
            return Ok(false);
        }
        if s == self.time_scale {
            return Ok(true);
        }
        let r = self.time_scale / s;
        for x in self.phases[FREE].s.iter_mut() {
            *x *= r;
        }
        self.set_time_scale_inner(scene, s);
        Ok(true)
    }

    /// [`set_time_scale`](Self::set_time_scale) at `pre`'s scale, its
    /// propagators copied from `pre` instead of computed, and its contact
    /// output rows too where `pre` holds them for this state's output band
    /// (bit for bit the same: `pre` was made by the same functions for
    /// `scene`). A `pre` made for another scene's step or block counts is
    /// not used: the propagators are then computed; rows made for another
    /// band are not used: the band is then applied, O(N M) for M modes
    /// left out. Otherwise O(N) copies, no transcendental function; no
    /// allocation. \[audio-thread\]
    pub fn set_time_scale_from(
        &mut self,
        scene: &CompiledScene,
        pre: &ScaleProps,
    ) -> Result<(), TimeScaleError> {
        scale_allowed(scene, pre.s)?;
        self.settle(scene);
        self.derive_for(scene, pre.s, false, Some(pre));
        Ok(())
    }

    pub(super) fn set_time_scale_inner(&mut self, scene: &CompiledScene, s: f64) {
        self.derive_for(scene, s, false, None);
    }

    /// Everything [`set_time_scale_inner`](Self::set_time_scale_inner)
    /// derives from the scene at time scale `s`; `free_kept`: the free
    /// phase's propagators are already those of `scene` at `s` (the same
    /// free phase, the same scale), so only the contact phase's are
    /// computed (one exponential and one sine/cosine per block fewer).
    /// `pre`: the propagators at `s`, made ahead ([`ScaleProps`]), copied
    /// where they fit the scene.
    pub(super) fn derive_for(
        &mut self,
        scene: &CompiledScene,
        s: f64,
        free_kept: bool,
        pre: Option<&ScaleProps>,
    ) {
        let free_kept = free_kept && s == self.time_scale && scene.h * s == self.step_s;
        let pre = pre.filter(|p| p.fits(scene, s));
        // physical velocity is preserved across a change of scale
        let v_phys = self.v_h * self.time_scale;
        self.time_scale = s;
        self.step_s = scene.h * s;
        // a contact's duration is counted in steps of one length
        self.rest_run = None;
        self.v_h = v_phys / s;
        if !free_kept {
            match pre {
                Some(p) => self.phases[FREE].props.copy_from(&p.free),
                None => fill_props(&mut self.phases[FREE].props, &scene.free, self.step_s),
            }
            self.phases[FREE].split.update(&scene.free, self.step_s);
        }
        match pre {
            Some(p) => self.phases[CONTACT].props.copy_from(&p.contact),
            None => fill_props(&mut self.phases[CONTACT].props, &scene.contact, self.step_s),
        }
        self.phases[CONTACT]
            .split
            .update(&scene.contact, self.step_s);
        self.part_ok = false;
        // Outputs in physical units: displacement rows as they are, velocity
        // rows times s (reference velocities are physical / s).
        for ch in 0..2 {
            mix_rows(&mut self.phases[FREE].out[ch], &scene.free, ch, s);
        }
        self.apply_band(scene, pre);
        self.g = scene.g * self.load;
        self.discontinuity();
    }

    /// Leave the struck object's modes whose frequency (at the current time
    /// scale, physical Hz) is above `band_hz` out of the outputs, in both
    /// phases, so a note pitched up never aliases its top modes back into
    /// the audio band. The dynamics are untouched (those modes still take
    /// part in the contact): only the pickup rows change, and they change
    /// consistently, because the contact rows are the free rows carried
    /// through `s_f = W_fc s_c + s_f*`: the output stays a continuous
    /// function of the physical state across every switch. `INFINITY` (the
    /// default) hears every mode; NaN or <= 0 is treated as `INFINITY`.
    /// A dense-fallback free phase has no modes to leave out (no effect).
    /// Allocation-free, O(N) plus O(N M) for M modes left out. \[audio-thread\]
    pub fn set_output_band(&mut self, scene: &CompiledScene, band_hz: f64) {
        self.settle(scene);
        self.band_hz = band_or_all(band_hz);
        // re-mix the rows (and apply the band) at the current scale
        self.set_time_scale_inner(scene, self.time_scale);
    }

    /// Modes currently left out of the outputs by the output band.
    pub fn band_muted_modes(&self) -> usize {
        self.band_muted
    }

    /// Mix the contact output rows at the current scale and leave the modes
    /// above the band out of them and of the free rows just mixed by
    /// `derive_for`: the free rows' entries zeroed, their contributions
    /// subtracted from the contact rows and offsets, O(N M) for M modes
    /// left out; or, where `pre` holds those contact rows for this band
    /// (made ahead by the same functions, so the same bits), O(N) copies
    /// of them instead.
    fn apply_band(&mut self, scene: &CompiledScene, pre: Option<&ScaleProps>) {
        let ahead = pre
            .and_then(|p| p.band.as_ref())
            .filter(|b| b.band_hz == self.band_hz);
        let [free, contact] = &mut self.phases;
        let free_rows = free.out.each_mut().map(|r| &mut r[..]);
        self.band_muted = match ahead {
            Some(b) => {
                for (dst, src) in contact.out.iter_mut().zip(&b.contact) {
                    dst.copy_from_slice(src);
                }
                self.out_c_offset = b.offset;
                band_out(scene, self.band_hz, self.time_scale, free_rows, None)
            }
            None => {
                for ch in 0..2 {
                    mix_rows(&mut contact.out[ch], &scene.contact, ch, self.time_scale);
                }
                self.out_c_offset = [scene.offsets.disp_l, scene.offsets.disp_r];
                let carry = (
                    contact.out.each_mut().map(|r| &mut r[..]),
                    &mut self.out_c_offset,
                );
                band_out(scene, self.band_hz, self.time_scale, free_rows, Some(carry))
            }
        };
    }
}

/// The one-sample block propagators `exp(G_k dt)` (libm's exp and sin_cos:
/// these are applied every sample, so they take the most accurate
/// functions; equal to `exp2` bit for bit).
fn fill_props(p: &mut BlockProps, ph: &CompiledPhase, dt: f64) {
    if let Some(gens) = &ph.gens {
        for (k, g) in gens.iter().enumerate() {
            p.set(k, &ph.osc.get(k).map_or_else(|| exp2(g, dt), |o| o.exp(dt)));
        }
    }
}

/// Whether `scene` may run at time scale `s`: finite and positive, and 1
/// for a scene with a dense phase (whose propagator is made at the
/// compile's step only).
fn scale_allowed(scene: &CompiledScene, s: f64) -> Result<(), TimeScaleError> {
    if !(s.is_finite() && s > 0.0) {
        return Err(TimeScaleError::Invalid);
    }
    if s != 1.0 && (scene.free.dense.is_some() || scene.contact.dense.is_some()) {
        return Err(TimeScaleError::DenseFallback);
    }
    Ok(())
}

impl ScaleProps {
    /// The propagators of `scene` at time scale `s`, and its contact
    /// output rows with the output band `band_hz` applied (the same
    /// functions, so the same bits, as `set_time_scale`'s on a state whose
    /// band is `band_hz`). \[worker\]
    pub fn new(scene: &CompiledScene, s: f64, band_hz: f64) -> Self {
        let step = scene.h * s;
        let of = |ph: &CompiledPhase| {
            let mut p = BlockProps::new(ph.gens.as_ref().map_or(0, Vec::len));
            fill_props(&mut p, ph, step);
            p
        };
        let rows = |ph: &CompiledPhase| {
            [0, 1].map(|ch| {
                let mut r = vec![0.0; ph.dim];
                mix_rows(&mut r, ph, ch, s);
                r
            })
        };
        let (mut free, mut contact) = (rows(&scene.free), rows(&scene.contact));
        let mut offset = [scene.offsets.disp_l, scene.offsets.disp_r];
        let band_hz = band_or_all(band_hz);
        let muted = band_out(
            scene,
            band_hz,
            s,
            free.each_mut().map(|r| &mut r[..]),
            Some((contact.each_mut().map(|r| &mut r[..]), &mut offset)),
        );
        Self {
            s,
            strike: None,
            step,
            free: of(&scene.free),
            contact: of(&scene.contact),
            band: (muted > 0).then_some(BandRows {
                band_hz,
                contact,
                offset,
            }),
        }
    }

    /// The time scale they are for.
    pub fn scale(&self) -> f64 {
        self.s
    }

    /// Made for `scene` at `s`: the same step and the same block counts
    /// (a check, not a proof: the caller pairs them with their scene).
    pub(super) fn fits(&self, scene: &CompiledScene, s: f64) -> bool {
        let nb = |ph: &CompiledPhase| ph.gens.as_ref().map_or(0, Vec::len);
        self.s == s
            && self.step == scene.h * s
            && self.free.len() == nb(&scene.free)
            && self.contact.len() == nb(&scene.contact)
    }
}

/// An output band as [`EngineState::set_output_band`] takes it: NaN or
/// <= 0 hears every mode (`INFINITY`).
fn band_or_all(band_hz: f64) -> f64 {
    if band_hz > 0.0 {
        band_hz
    } else {
        f64::INFINITY
    }
}

/// Zero the entries of the free output rows `free` (mixed at time scale
/// `s`) of the modes whose frequency is above `band_hz` (physical Hz);
/// with `carry`, subtract each zeroed entry's contribution from the
/// contact rows and offsets (the contact rows are the free rows carried
/// through `s_f = W_fc s_c + s_f*`). Returns how many modes are left out.
/// O(N), plus O(N) per mode left out with `carry`. \[audio-thread\]
/// \[worker\]
fn band_out(
    scene: &CompiledScene,
    band_hz: f64,
    s: f64,
    mut free: [&mut [f64]; 2],
    mut carry: Option<([&mut [f64]; 2], &mut [f64; 2])>,
) -> usize {
    let Some(gens) = scene.free.gens.as_ref() else {
        return 0;
    };
    if !band_hz.is_finite() {
        return 0;
    }
    let nb = gens.len();
    // omega_phys = omega_ref * s; muted when omega_ref * s > 2 pi band
    let limit = 2.0 * std::f64::consts::PI * band_hz / s;
    let (df, dc) = (scene.w_fc.nrows(), scene.contact.dim);
    let mut muted = 0;
    for (k, g) in gens.iter().enumerate() {
        let half_tr = 0.5 * (g[0] + g[3]);
        let det = g[0] * g[3] - g[1] * g[2];
        let w2 = det - half_tr * half_tr;
        if !(w2 > limit * limit) {
            continue;
        }
        muted += 1;
        for i in [k, nb + k] {
            let r = [free[0][i], free[1][i]];
            for (f, r) in free.iter_mut().zip(r) {
                if r != 0.0 {
                    f[i] = 0.0;
                }
            }
            let Some(([out_l, out_r], offset)) = carry.as_mut() else {
                continue;
            };
            // row i of W_fc, strided through its column-major storage,
            // read once for both channels; each entry takes the same
            // subtractions in the same order as one channel at a time
            let row = scene.w_fc.as_slice()[i..].iter().step_by(df);
            let (out_l, out_r) = (&mut out_l[..dc], &mut out_r[..dc]);
            match (r[0] != 0.0, r[1] != 0.0) {
                (true, true) => {
                    for ((a, b), w) in out_l.iter_mut().zip(out_r.iter_mut()).zip(row) {
                        *a -= r[0] * w;
                        *b -= r[1] * w;
                    }
                }
                (true, false) => out_l.iter_mut().zip(row).for_each(|(a, w)| *a -= r[0] * w),
                (false, true) => out_r.iter_mut().zip(row).for_each(|(b, w)| *b -= r[1] * w),
                (false, false) => {}
            }
            for ch in 0..2 {
                if r[ch] != 0.0 {
                    offset[ch] -= r[ch] * scene.s_f_star[i];
                }
            }
        }
    }
    muted
}

fn mix_rows(dst: &mut [f64], ph: &CompiledPhase, ch: usize, s: f64) {
    let (d, v) = if ch == 0 {
        (&ph.rows.disp_l, &ph.rows.vel_l)
    } else {
        (&ph.rows.disp_r, &ph.rows.vel_r)
    };
    for ((o, a), b) in dst.iter_mut().zip(d).zip(v) {
        *o = a + b * s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compile::compile_one;
    use crate::engine::Phase;
    use crate::presets;

    /// The contact output rows and offsets at time scale `s` with the modes
    /// above `band_hz` left out, written the plain way: each left-out
    /// free-row entry carried through `W_fc` entry by entry, one channel
    /// at a time.
    fn band_reference(sc: &CompiledScene, s: f64, band_hz: f64) -> ([Vec<f64>; 2], [f64; 2]) {
        let mix = |ph: &crate::compile::CompiledPhase, ch: usize| -> Vec<f64> {
            let (d, v) = if ch == 0 {
                (&ph.rows.disp_l, &ph.rows.vel_l)
            } else {
                (&ph.rows.disp_r, &ph.rows.vel_r)
            };
            d.iter().zip(v).map(|(a, b)| a + b * s).collect()
        };
        let mut free = [mix(&sc.free, 0), mix(&sc.free, 1)];
        let mut contact = [mix(&sc.contact, 0), mix(&sc.contact, 1)];
        let mut offset = [sc.offsets.disp_l, sc.offsets.disp_r];
        let gens = sc.free.gens.as_ref().unwrap();
        let nb = gens.len();
        let limit = 2.0 * std::f64::consts::PI * band_hz / s;
        for (k, g) in gens.iter().enumerate() {
            let half_tr = 0.5 * (g[0] + g[3]);
            let w2 = g[0] * g[3] - g[1] * g[2] - half_tr * half_tr;
            if !(w2 > limit * limit) {
                continue;
            }
            for ch in 0..2 {
                for i in [k, nb + k] {
                    let r = free[ch][i];
                    if r == 0.0 {
                        continue;
                    }
                    free[ch][i] = 0.0;
                    for j in 0..sc.contact.dim {
                        contact[ch][j] -= r * sc.w_fc[(i, j)];
                    }
                    offset[ch] -= r * sc.s_f_star[i];
                }
            }
        }
        (contact, offset)
    }

    #[test]
    fn propagators_made_ahead_are_the_computed_ones_bit_for_bit() {
        // every one-contact preset at three scales, with every mode heard
        // and with an output band that leaves the top modes out: the
        // propagators and output rows copied from a `ScaleProps` are
        // `set_time_scale`'s bit for bit; one made for another scene
        // (other block counts or step) is not used, nor are band rows
        // made for another band
        let other = compile_one(
            &presets::scene(presets::one_contact().next().unwrap()).unwrap(),
            48000.0,
        )
        .unwrap();
        let bits = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
        };
        let mut band_rows_used = 0;
        for i in presets::one_contact() {
            let sc = compile_one(&presets::scene(i).unwrap(), 44100.0).unwrap();
            if sc.free.gens.is_none() || sc.contact.gens.is_none() {
                continue;
            }
            for s in [0.5, 1.0, 2f64.powf(7.0 / 12.0)] {
                for band in [f64::INFINITY, 3000.0] {
                    let mut want = EngineState::new(&sc);
                    want.set_output_band(&sc, band);
                    want.set_time_scale(&sc, s).unwrap();
                    for (k, pre) in [
                        ScaleProps::new(&sc, s, band),
                        ScaleProps::new(&sc, s, 1234.5),
                        ScaleProps::new(&other, s, band),
                    ]
                    .iter()
                    .enumerate()
                    {
                        let mut got = EngineState::new(&sc);
                        got.set_output_band(&sc, band);
                        got.set_time_scale_from(&sc, pre).unwrap();
                        assert_eq!(got.step_s.to_bits(), want.step_s.to_bits());
                        for ph in [Phase::Free, Phase::Contact] {
                            let (g, w) = (&got.phases[ph.index()], &want.phases[ph.index()]);
                            for (a, b) in [
                                (&g.props.p00, &w.props.p00),
                                (&g.props.p01, &w.props.p01),
                                (&g.props.p10, &w.props.p10),
                                (&g.props.p11, &w.props.p11),
                            ] {
                                assert!(bits(a, b), "preset {i} at {s}: {ph:?} propagators");
                            }
                            for ch in 0..2 {
                                assert!(
                                    bits(&g.out[ch], &w.out[ch]),
                                    "preset {i} at {s}, band {band}: {ph:?} output row {ch}"
                                );
                            }
                        }
                        assert!(bits(&got.out_c_offset, &want.out_c_offset));
                        let (rows, offset) = band_reference(&sc, s, band);
                        for ch in 0..2 {
                            assert!(
                                bits(&want.phases[Phase::Contact.index()].out[ch], &rows[ch]),
                                "preset {i} at {s}, band {band}: contact row {ch} against the reference"
                            );
                        }
                        assert!(bits(&want.out_c_offset, &offset));
                        assert_eq!(got.band_muted_modes(), want.band_muted_modes());
                        if k == 0 && pre.band.is_some() {
                            assert!(want.band_muted_modes() > 0);
                            band_rows_used += 1;
                        }
                    }
                }
            }
        }
        println!("band rows copied in {band_rows_used} cases");
        assert!(band_rows_used >= 10, "{band_rows_used}");
    }
}
