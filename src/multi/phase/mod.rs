//! Compiling a phase (the contacts of a mask closed): its coordinates, its
//! block decomposition and every row the engine reads ([`MultiPhase`]);
//! the compiled model ([`CompiledMulti`]) and the per-state tables.

use super::*;
use crate::engine::kernel::EVENT_ROWS;

mod coupled;
mod rows;
mod structured;
mod whole;

use coupled::{CoupledBlocks, CoupledForces, CoupledPart, CoupledSystem};
use rows::{EventRows, PhaseRows, SwitchProducts};
pub(super) use structured::{product, StructuredProducts, SwitchScratch};
use whole::WholePhase;

impl Layout {
    fn new(m: &MultiModel, members: &[usize]) -> Self {
        let nm = m.masses.len();
        let mut parent: Vec<usize> = (0..nm).collect();
        fn root(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        let mut in_contact = vec![false; nm];
        let mut held = vec![false; nm];
        for &c in members {
            let ct = &m.contacts[c];
            match (&ct.lower, &ct.upper) {
                (MultiEnd::Mass(a), MultiEnd::Mass(b)) => {
                    in_contact[*a] = true;
                    in_contact[*b] = true;
                    let (ra, rb) = (root(&mut parent, *a), root(&mut parent, *b));
                    parent[ra] = rb;
                }
                (MultiEnd::Mass(a), _) | (_, MultiEnd::Mass(a)) => {
                    in_contact[*a] = true;
                    held[*a] = true;
                }
                _ => {}
            }
        }
        let mut root_held = vec![false; nm];
        for j in 0..nm {
            if held[j] {
                let r = root(&mut parent, j);
                root_held[r] = true;
            }
        }
        let mut bound = vec![];
        let mut place = vec![None; nm];
        let mut group_of_root: Vec<Option<usize>> = vec![None; nm];
        let mut groups: Vec<Vec<usize>> = vec![];
        let mut fly_of = vec![None; nm];
        for j in 0..nm {
            if !in_contact[j] {
                fly_of[j] = Some(j);
                continue;
            }
            place[j] = Some(bound.len());
            bound.push(j);
            let r = root(&mut parent, j);
            if !root_held[r] {
                let g = *group_of_root[r].get_or_insert_with(|| {
                    groups.push(vec![]);
                    groups.len() - 1
                });
                groups[g].push(j);
                fly_of[j] = Some(groups[g][0]);
            }
        }
        Self {
            bound,
            place,
            groups,
            fly_of,
        }
    }
}

impl MultiPhase {
    /// The phase of `mask`, each contact's stage below given
    /// ([`MultiModel::stage_below`]).
    fn new(
        m: &MultiModel,
        mask: u32,
        h: f64,
        stage_below: &[Option<usize>],
    ) -> Result<Self, MultiError> {
        let members: Vec<usize> = (0..m.contacts.len())
            .filter(|j| mask & (1 << j) != 0)
            .collect();
        let lay = Layout::new(m, &members);
        let rows = contact_rows_z(m, &lay, &members);
        let p0: Vec<f64> = rows.iter().map(|r| r.1).collect();
        let cp = CoupledPart::new(m, &lay, &rows);
        let cf = CoupledForces::new(m, &lay, &members, &rows, &p0, &cp);
        let cs = CoupledSystem::new(&cp, &cf, mask)?;
        let blocks = CoupledBlocks::new(&cs.a, h, mask)?;
        let kappa = blocks.kappa;
        let eq = cs.equilibrium(&cp, &cf.rod_force, mask)?;
        let w = WholePhase::new(m, &lay, &members, &cp, &cs, blocks, &eq);
        let growth: Vec<f64> = w.gens.iter().map(|g| (sym_growth(g) * h).exp()).collect();
        let growth_max = growth.iter().copied().fold(1.0, f64::max);
        let phase_rows = PhaseRows {
            m,
            lay: &lay,
            w: &w,
        };
        let er = phase_rows.events(&members, &p0);
        let shadow = shadows(stage_below, mask, &er);
        let (kernel_row, kernel_obs) = kernel_rows(&shadow);
        let sides = phase_rows.sides();
        let out = phase_rows.outputs();
        // the entries of s the coupled part moves (the free modes' blocks
        // are their own (omega q, q'))
        let coupled: Vec<usize> = (0..cs.dimc).map(|c| w.smap(c)).collect();
        let sp = SwitchProducts::new(m.n(), &lay, &members, &cp.cm, &w, &coupled);
        let structured = StructuredProducts::new(&m.freq_hz, &cp.cm, &sp, &coupled, &w.gens);
        let mut flyers: Vec<usize> = (0..m.masses.len())
            .filter(|&j| lay.place[j].is_none())
            .collect();
        flyers.extend(lay.groups.iter().map(|grp| grp[0]));
        let free_blocks: Vec<(usize, usize, usize)> = cp
            .fm
            .iter()
            .enumerate()
            .map(|(j, &i)| (i, w.nbc + j, w.nb + w.nbc + j))
            .collect();
        let forms = w.gens.iter().map(OscForm::of).collect();
        Ok(Self {
            members,
            dim: w.dim,
            forms,
            ev_blocks: er.ev_blocks,
            ev_nz: er.ev_nz,
            evd_nz: er.evd_nz,
            gens: w.gens,
            qv0: sp.qv0,
            pv0: sp.pv0,
            zv0: sp.zv0,
            qv: sp.qv,
            pv: sp.pv,
            zv: sp.zv,
            qv_c: sp.qv_c,
            qv_rows: sp.qv_rows,
            pv_c: sp.pv_c,
            pv_rows: sp.pv_rows,
            zv_c: sp.zv_c,
            bound_rows: (0..lay.bound.len()).collect(),
            vq_c: sp.vq_c,
            vp_c: sp.vp_c,
            structured,
            free_blocks,
            s_star: sp.s_star,
            bound: lay.bound,
            place: lay.place,
            groups: lay.groups,
            fly_of: lay.fly_of,
            flyers,
            p0,
            rod_s: w.rod_s,
            kernel_ready: kernel_row.iter().all(Option::is_some),
            kernel_row,
            kernel_obs,
            shadow,
            ev: er.ev,
            ev0: er.ev0,
            ev_d: er.ev_d,
            ev_c2: er.ev_c2,
            ev_e: er.ev_e,
            ev_fly: er.ev_fly,
            search: er.search,
            sides,
            coupled,
            coupled_modes: cp.cm,
            out_d: out.out_d,
            out_d0: out.out_d0,
            out_v: out.out_v,
            out_v0: out.out_v0,
            kappa,
            growth: growth_max,
        })
    }
}

/// A phase that cannot be compiled, and why.
fn phase_error(mask: u32, why: String) -> MultiError {
    MultiError::Phase { mask, why }
}

/// Each closed contact's row over z and constant: `p = g . z + p0`.
fn contact_rows_z(m: &MultiModel, lay: &Layout, members: &[usize]) -> Vec<(Vec<f64>, f64)> {
    let n = m.n();
    let nz = n + lay.bound.len();
    let sqm = |j: usize| m.masses[j].mass_kg.sqrt();
    let row_z = |e: &MultiEnd| -> (Vec<f64>, f64) {
        let mut r = vec![0.0; nz];
        match e {
            MultiEnd::Point(w) => {
                r[..n].copy_from_slice(w);
                (r, 0.0)
            }
            MultiEnd::Mass(j) => {
                if let Some(b) = lay.place[*j] {
                    r[n + b] = 1.0 / sqm(*j);
                }
                (r, 0.0)
            }
            MultiEnd::Wall(hw) => (r, *hw),
        }
    };
    let contact_z = |c: usize| {
        let ct = &m.contacts[c];
        let (rl, cl) = row_z(&ct.lower);
        let (ru, cu) = row_z(&ct.upper);
        let r: Vec<f64> = rl.iter().zip(&ru).map(|(a, b)| a - b).collect();
        (r, cl - cu - ct.gap_m)
    };
    members.iter().map(|&c| contact_z(c)).collect()
}

/// Each contact's row in the block kernel ([`MultiPhase::kernel_row`]):
/// a contact in the shadow of an open stage below ([`shadows`]) reads the
/// row of the lowest stage down that chain (the same numbers: only the
/// constant differs), any other contact its own; `None` for a row at or
/// beyond [`EVENT_ROWS`]. Then the observation rows the kernel must sum
/// for them ([`MultiPhase::kernel_obs`]: 0, 1 or 3).
fn kernel_rows(shadow: &[Option<(usize, f64)>]) -> (Vec<Option<usize>>, usize) {
    let rows: Vec<Option<usize>> = (0..shadow.len())
        .map(|j| {
            let mut i = j;
            while let Some((b, _)) = shadow[i] {
                i = b;
            }
            (i < EVENT_ROWS).then_some(i)
        })
        .collect();
    let obs = match rows.iter().flatten().max() {
        None | Some(0) => 0,
        Some(1) => 1,
        Some(_) => EVENT_ROWS - 1,
    };
    (rows, obs)
}

/// Each contact's shadowing stage in the phase of `mask`
/// ([`MultiPhase::shadow`]): for an open contact whose stage below is open
/// with its row and flights bit for bit (the same sides), that stage and
/// how much deeper this one lies (`d > 0`: its penetration is the stage's
/// less `d`); `None` for any other.
fn shadows(stage_below: &[Option<usize>], mask: u32, er: &EventRows) -> Vec<Option<(usize, f64)>> {
    let open = |i: usize| mask & (1 << i) == 0;
    let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
    (0..er.ev.len())
        .map(|j| {
            let i = stage_below[j]?;
            let d = er.ev0[i] - er.ev0[j];
            (open(j)
                && open(i)
                && same(&er.ev[i], &er.ev[j])
                && er.ev_fly[i] == er.ev_fly[j]
                && d > 0.0)
                .then_some((i, d))
        })
        .collect()
}

impl CompiledMulti {
    /// Compile every phase that can be reached
    /// ([`MultiModel::reachable_masks`]: `2^K` of them for `K` contacts
    /// of which none is a stage of another, `P + 1` for a law of `P`
    /// pieces) at `rate_hz`.
    pub fn new(model: &MultiModel, rate_hz: f64) -> Result<Self, MultiError> {
        Self::compile(model, rate_hz, false)
    }

    /// TEST ONLY: [`new`](Self::new) with all `2^K` phases, the ones
    /// never reached too, as a check that leaving them out changes
    /// nothing.
    #[doc(hidden)]
    pub fn with_every_phase(model: &MultiModel, rate_hz: f64) -> Result<Self, MultiError> {
        Self::compile(model, rate_hz, true)
    }

    fn compile(model: &MultiModel, rate_hz: f64, every: bool) -> Result<Self, MultiError> {
        model.validate()?;
        check_value("rate_hz", rate_hz, rate_hz > 0.0)?;
        let k = model.contacts.len();
        let stage_below = model.stage_below();
        let reachable = model.reachable_masks_of(&stage_below);
        model.within_budget_of(reachable.len())?;
        let masks: Vec<u32> = if every {
            (0..1u32 << k).collect()
        } else {
            reachable
        };
        let h = 1.0 / rate_hz;
        let phases = masks
            .iter()
            .map(|&mask| MultiPhase::new(model, mask, h, &stage_below))
            .collect::<Result<Vec<_>, _>>()?;
        let mut slots = vec![u32::MAX; 1 << k];
        for (i, &mask) in masks.iter().enumerate() {
            slots[mask as usize] = i as u32;
        }
        let mut below = [0u32; MAX_SPRINGS];
        for (b, s) in below.iter_mut().zip(stage_below) {
            *b = s.map_or(0, |i| 1 << i);
        }
        Ok(Self {
            model: model.clone(),
            h,
            rate_hz,
            phases,
            slots,
            below,
            switching: Switching::Exact,
        })
    }

    /// Whether contact `j` is a stage of another (a law's further piece:
    /// [`MultiModel::stage_below`]).
    pub fn is_stage(&self, j: usize) -> bool {
        self.below.get(j).is_some_and(|&b| b != 0)
    }

    /// The index in [`phases`](Self::phases) of the phase of `mask`, a
    /// mask that is reached (the switch keeps every state's mask so:
    /// [`staged`](Self::staged)). O(1). \[audio-thread\]
    pub fn slot(&self, mask: u32) -> usize {
        self.slots[mask as usize] as usize
    }

    /// The contacts that switch when `who` would from `mask`, so that the
    /// new mask is one that is reached: a contact whose stage below
    /// leaves leaves with it, and a contact that enters takes its stage
    /// below in with it if that one is open (each stage's penetration is
    /// the one below's less the difference of their offsets, so in exact
    /// arithmetic neither happens; with the offset rod, stages that
    /// entered at one sample instant leave at one, which their rods'
    /// rounding may split). Both are passive: a contact that leaves
    /// takes its spring's energy out, one that enters starts at its rod
    /// or unstretched. O(K) without stages, O(K^2) with. \[audio-thread\]
    pub fn staged(&self, mask: u32, who: u32) -> u32 {
        let k = self.contacts();
        if self.below[..k].iter().all(|&b| b == 0) {
            // no stages: nothing else switches
            return who;
        }
        let mut new = mask ^ who;
        // a stage leaves when the one below it leaves (up the chain)
        for _ in 0..k {
            for (j, &b) in self.below.iter().enumerate().take(k) {
                if new & (1 << j) != 0 && new & b == 0 && mask & b != 0 {
                    new &= !(1 << j);
                }
            }
        }
        // an entering stage takes the one below in (down the chain)
        for _ in 0..k {
            for (j, &b) in self.below.iter().enumerate().take(k) {
                if new & (1 << j) != 0 {
                    new |= b;
                }
            }
        }
        mask ^ new
    }

    /// [`new`](Self::new) with the given switching method (the scene's
    /// `contact.switching`).
    pub fn with_switching(
        model: &MultiModel,
        rate_hz: f64,
        switching: Switching,
    ) -> Result<Self, MultiError> {
        let mut sc = Self::new(model, rate_hz)?;
        sc.switching = switching;
        Ok(sc)
    }

    /// Number of contacts.
    pub fn contacts(&self) -> usize {
        self.model.contacts.len()
    }

    /// The largest condition number of the phases' `V`.
    pub fn kappa(&self) -> f64 {
        self.phases.iter().map(|p| p.kappa).fold(1.0, f64::max)
    }

    /// The largest block growth over one sample of any phase
    /// ([`MultiPhase::growth`]).
    pub fn growth(&self) -> f64 {
        self.phases.iter().map(|p| p.growth).fold(1.0, f64::max)
    }

    /// The largest phase dimension.
    pub fn max_dim(&self) -> usize {
        self.phases.iter().map(|p| p.dim).max().unwrap_or(0)
    }

    /// Of the switch products of every phase (four per phase: into and out
    /// of its coupled part's physical coordinates), how many are in
    /// hierarchical low-rank form, and how many there are
    /// (docs/numerics.md section 14, "Structured switches").
    pub fn structured_products(&self) -> (usize, usize) {
        let n = self.phases.iter().map(|p| p.structured.count()).sum();
        (n, 4 * self.phases.len())
    }

    /// TEST ONLY: drop the structured products (every switch then takes
    /// the dense ones), as a check of the structured form against them.
    #[doc(hidden)]
    pub fn forget_structured(&mut self) {
        for p in &mut self.phases {
            p.structured = StructuredProducts::default();
        }
    }
}

impl PhaseTables {
    pub(super) fn new(ph: &MultiPhase) -> Self {
        Self {
            props: vec![[0.0; 4]; ph.gens.len()],
            soa: BlockProps::new(ph.gens.len()),
            growth: vec![1.0; ph.gens.len()],
            growth_max: 1.0,
            ev_c2: ph.ev_c2.clone(),
            ev_e: ph.ev_e.clone(),
            ev_c1: ph.search.c1.clone(),
            ev_c3: ph.search.c3.clone(),
            ev_c4: ph.search.c4.clone(),
            out: [vec![0.0; ph.dim], vec![0.0; ph.dim]],
            out0: [0.0; 2],
            at: f64::NAN,
            limit: f64::INFINITY,
            muted: 0,
        }
    }

    /// Bring them to `scale` (step `h` of the model's time) and the output
    /// band `band_hz` (physical; infinite: every mode heard). O(dim), plus
    /// O(dim) per mode left out, allocation-free.
    pub(super) fn make(
        &mut self,
        ph: &MultiPhase,
        m: &MultiModel,
        scale: f64,
        h: f64,
        band_hz: f64,
    ) {
        let limit = two_pi() * band_hz / scale;
        if self.at == scale && self.limit == limit {
            return;
        }
        self.growth_max = 1.0;
        for (k, g) in ph.gens.iter().enumerate() {
            self.props[k] = exp2(g, h);
            self.soa.set(k, &self.props[k]);
            self.growth[k] = (sym_growth(g) * h).exp();
            self.growth_max = self.growth_max.max(self.growth[k]);
        }
        for j in 0..self.ev_e.len() {
            for k in 0..ph.gens.len() {
                let g = self.growth[k];
                self.ev_c2[j][k] = ph.ev_c2[j][k] * g;
                self.ev_e[j][k] = ph.ev_e[j][k] * g;
                self.ev_c1[j][k] = ph.search.c1[j][k] * g;
                self.ev_c3[j][k] = ph.search.c3[j][k] * g;
                self.ev_c4[j][k] = ph.search.c4[j][k] * g;
            }
        }
        for c in 0..2 {
            for (o, (d, v)) in self.out[c]
                .iter_mut()
                .zip(ph.out_d[c].iter().zip(&ph.out_v[c]))
            {
                *o = d + scale * v;
            }
            self.out0[c] = ph.out_d0[c] + scale * ph.out_v0[c];
        }
        // a mode above the band leaves the outputs: its share of each row
        // (`q_i = (Q u)_i / omega_i`, `q'_i = (P w)_i`, the rows a switch
        // takes the physical state through) is taken out, in every phase
        // alike, so the output stays a continuous function of the
        // physical state across switches; its dynamics stay
        self.muted = 0;
        for i in 0..m.n() {
            let w = two_pi() * m.freq_hz[i];
            if !(w > limit) {
                continue;
            }
            self.muted += 1;
            for c in 0..2 {
                let (a, b) = (m.pickups[c].0[i] / w, scale * m.pickups[c].1[i]);
                if a == 0.0 && b == 0.0 {
                    continue;
                }
                for (col, o) in self.out[c].iter_mut().enumerate() {
                    *o -= a * ph.qv[(i, col)] + b * ph.pv[(i, col)];
                }
                self.out0[c] -= a * ph.qv0[i] + b * ph.pv0[i];
            }
        }
        self.at = scale;
        self.limit = limit;
    }
}

impl MultiPhase {
    /// The physical state of the phase's `y` (the flights from `fly`).
    /// With `scratch` (a switch) the coupled products take their
    /// hierarchical form where the phase has one; without (a check, a
    /// carry), the dense products.
    pub(super) fn physical_of(
        &self,
        m: &MultiModel,
        s: &[f64],
        (x_f, v_f): (&[f64], &[f64]),
        (zq, zv): (&mut [f64], &mut [f64]),
        out: &mut Physical,
        mut scratch: Option<(&mut SwitchScratch, SimdPath)>,
    ) {
        let n = m.n();
        // a free mode's block is its own (omega q, q')
        for &(i, k1, k2) in &self.free_blocks {
            out.q[i] = s[k1] / (two_pi() * m.freq_hz[i]);
            out.qv[i] = s[k2];
        }
        // the coupled modes' q from Q u = (omega q, ...), z' = P w, the
        // held masses' x from Z u (the part off the free groups' centres)
        for &r in &self.qv_rows {
            zq[r] = self.qv0[r];
        }
        let st = &self.structured;
        product(
            st.qv.as_ref(),
            &self.qv_c,
            (&self.coupled, s),
            &self.qv_rows,
            zq,
            scratch.as_mut().map(|(sw, path)| (&mut **sw, *path)),
        );
        for &i in &self.coupled_modes {
            out.q[i] = zq[i] / (two_pi() * m.freq_hz[i]);
        }
        for &r in &self.pv_rows {
            zv[r] = self.pv0[r];
        }
        product(
            st.pv.as_ref(),
            &self.pv_c,
            (&self.coupled, s),
            &self.pv_rows,
            zv,
            scratch,
        );
        for &i in &self.coupled_modes {
            out.qv[i] = zv[i];
        }
        let nb = self.bound.len();
        zq[..nb].copy_from_slice(&self.zv0);
        mat_vec_idx(&self.zv_c, (&self.coupled, s), &self.bound_rows, zq);
        for (j, ms) in m.masses.iter().enumerate() {
            match self.place[j] {
                Some(b) => {
                    let s = ms.mass_kg.sqrt();
                    let (mut x, mut v) = (zq[b] / s, zv[n + b] / s);
                    if let Some(k) = self.fly_of[j] {
                        x += x_f[k];
                        v += v_f[k];
                    }
                    out.x[j] = x;
                    out.v[j] = v;
                }
                None => {
                    out.x[j] = x_f[j];
                    out.v[j] = v_f[j];
                }
            }
        }
    }

    /// The phase's block state `s` of a physical state whose closed
    /// contacts' penetrations are `pen` (by contact), and its flights: `u =
    /// Q^T (omega q, sqrt(k_c) (p_c - p0_c))`, `w = P^T z'`, `s = V^-1 (y -
    /// y*)`.
    /// The penetrations come apart from the positions: as a difference of
    /// two sides a heavy hammer's would keep `u |x|` of error.
    /// `scratch` as in [`physical_of`](Self::physical_of).
    pub(super) fn state_of(
        &self,
        m: &MultiModel,
        (ph, pen): (&Physical, &[f64; MAX_SPRINGS]),
        (x_f, v_f): (&mut [f64], &mut [f64]),
        (zq, zv): (&mut [f64], &mut [f64]),
        s: &mut [f64],
        mut scratch: Option<(&mut SwitchScratch, SimdPath)>,
    ) {
        let n = m.n();
        for i in 0..n {
            zq[i] = two_pi() * m.freq_hz[i] * ph.q[i];
        }
        for (pos, &c) in self.members.iter().enumerate() {
            zq[n + pos] = m.contacts[c].stiffness_n_per_m.sqrt() * (pen[c] - self.p0[pos]);
        }
        zv[..n].copy_from_slice(&ph.qv);
        for (b, &j) in self.bound.iter().enumerate() {
            zv[n + b] = m.masses[j].mass_kg.sqrt() * ph.v[j];
        }
        for (j, place) in self.place.iter().enumerate() {
            if place.is_none() {
                x_f[j] = ph.x[j];
                v_f[j] = ph.v[j];
            }
        }
        for grp in &self.groups {
            let total: f64 = grp.iter().map(|&j| m.masses[j].mass_kg).sum();
            let (mut x, mut v) = (0.0, 0.0);
            for &j in grp {
                x += m.masses[j].mass_kg * ph.x[j];
                v += m.masses[j].mass_kg * ph.v[j];
            }
            x_f[grp[0]] = x / total;
            v_f[grp[0]] = v / total;
        }
        for (o, x) in s.iter_mut().zip(&self.s_star) {
            *o = -x;
        }
        // a free mode's block is its own (omega q, q') (its `s*` is 0);
        // the coupled entries through the coupled part's products
        for &(i, k1, k2) in &self.free_blocks {
            s[k1] += zq[i];
            s[k2] += zv[i];
        }
        let st = &self.structured;
        product(
            st.vq.as_ref(),
            &self.vq_c,
            (&self.qv_rows, zq),
            &self.coupled,
            s,
            scratch.as_mut().map(|(sw, path)| (&mut **sw, *path)),
        );
        product(
            st.vp.as_ref(),
            &self.vp_c,
            (&self.pv_rows, zv),
            &self.coupled,
            s,
            scratch,
        );
    }
}
