//! The trace of a render (docs/design.md, "Offline rendering"): its rows
//! and header, the [`TraceSink`] a render hands every sample to, the rows
//! kept in memory and a pair of sinks fed the same samples.

use crate::engine::{Motion, Observation};

/// One trace row (docs/design.md, "The render command and the trace CSV"): row `n` is time `n / fs`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    /// Time \[s\].
    pub t: f64,
    /// The observation at that time, after the switching decision.
    pub obs: Observation,
    /// A driven scene's path position and the surface's height under the
    /// contact at that time \[m\] ([`DRIVE_COLUMNS`]; zeros for a scene
    /// that is not driven, whose trace has no such columns).
    pub surface: [f64; 2],
}

impl TraceRow {
    /// The row's numbers in the order of [`TRACE_HEADER`] (`in_contact` 0
    /// or 1).
    pub fn columns(&self) -> [f64; 7] {
        let o = &self.obs;
        [
            self.t,
            o.x_hammer,
            o.v_hammer,
            o.x_contact,
            o.v_contact,
            f64::from(u8::from(o.in_contact)),
            o.energy,
        ]
    }
}

/// The trace CSV header (docs/design.md, "The render command and the trace CSV").
pub const TRACE_HEADER: &str = "t,x_hammer,v_hammer,x_contact,v_contact,in_contact,energy";

/// The columns a driven scene's trace adds after [`TRACE_HEADER`]
/// (docs/design.md, "Rolling and scraping"): the path position \[m\] and
/// the surface's height under the contact \[m\] (from its height at the
/// path's start; `x_hammer` is relative to it: the hammer's height in the
/// room is `x_hammer + surface`).
pub const DRIVE_COLUMNS: &str = "path,surface";

/// The trace's header of a driven scene ([`DRIVE_COLUMNS`] after
/// [`TRACE_HEADER`]) or of `contacts` contacts ([`trace_header`]; a driven
/// scene has one contact).
pub fn trace_header_with(contacts: usize, driven: bool) -> String {
    let mut h = trace_header(contacts);
    if driven {
        h.push(',');
        h.push_str(DRIVE_COLUMNS);
    }
    h
}

/// The trace's header for `contacts` contacts (docs/design.md, "Several
/// contacts"): [`TRACE_HEADER`] for contact 0 (`energy` the total), then
/// `x_hammer_j, v_hammer_j, x_contact_j, v_contact_j, in_contact_j` for
/// each further contact `j`.
pub fn trace_header(contacts: usize) -> String {
    let mut h = String::from(TRACE_HEADER);
    for j in 1..contacts {
        h.push_str(&format!(
            ",x_hammer_{j},v_hammer_{j},x_contact_{j},v_contact_{j},in_contact_{j}"
        ));
    }
    h
}

/// Where a render's trace goes, sample by sample (docs/design.md, "Offline
/// rendering"): the full rows, a CSV file, the plot's envelope, or several.
pub trait TraceSink {
    /// Whether sample `i` needs the energy (it costs more than the motion,
    /// see [`EngineState::energy`](crate::engine::EngineState::energy)).
    fn wants_energy(&self, i: usize) -> bool;
    /// Record sample `i` (time `i / fs`): its motion, and its energy when
    /// [`wants_energy`](Self::wants_energy) said so.
    fn record(&mut self, i: usize, motion: &Motion, energy: Option<f64>) -> std::io::Result<()>;
    /// Record sample `i` of a several-contact render: each contact's motion
    /// (contact 0 first) and the total energy. A sink that keeps one
    /// contact's motion takes a single motion and refuses more (an error,
    /// not a dropped column); the trace files, the rows in memory and the
    /// plot's envelope take every contact.
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        energy: Option<f64>,
    ) -> std::io::Result<()> {
        match motions {
            [m] => self.record(i, m, energy),
            _ => Err(std::io::Error::other(format!(
                "this trace takes one contact, the render has {}",
                motions.len()
            ))),
        }
    }
    /// Record sample `i` of a driven scene: its motion, its energy when
    /// asked for, and `surface`, the path position and the surface's height
    /// under the contact \[m\] ([`DRIVE_COLUMNS`]). Every sink says what
    /// it does with the surface (no default, so a wrapper cannot drop it
    /// by forgetting): the trace files and the rows in memory keep it (a
    /// trace file made for a scene that is not driven refuses it: an
    /// error, not a dropped column); the plot's envelope, which draws no
    /// surface, takes the motion.
    fn record_driven(
        &mut self,
        i: usize,
        motion: &Motion,
        energy: Option<f64>,
        surface: [f64; 2],
    ) -> std::io::Result<()>;
    /// Whether the sink wants the energy of (nearly) every sample. When it
    /// does not, the render runs the engine's block path with the motion
    /// ([`EngineState::process_block_observed`], one kernel pass summing
    /// the contact point's rows too) and takes the energy only where asked.
    ///
    /// [`EngineState::process_block_observed`]: crate::engine::EngineState::process_block_observed
    fn every_energy(&self) -> bool {
        true
    }
    /// Whether the sink needs the values of the engine's per-sample path
    /// ([`EngineState::tick_with`]) bit for bit (the in-memory rows the
    /// tests compare against). When it does not, a sink that wants every
    /// energy gets the block path's motion and energy
    /// ([`EngineState::process_block_traced`]), equal up to the order of
    /// the sums and O(N) per sample wherever the phase allows.
    ///
    /// [`EngineState::tick_with`]: crate::engine::EngineState::tick_with
    /// [`EngineState::process_block_traced`]: crate::engine::EngineState::process_block_traced
    fn needs_ticks(&self) -> bool {
        true
    }
    /// Record the consecutive samples `first..first + motion.len()`, each
    /// with its energy (`energy[k]` for sample `first + k`; the sink keeps
    /// it where [`wants_energy`](Self::wants_energy) says): what the
    /// render hands a sink that wants every energy, one call per chunk.
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        for (k, (m, &e)) in motion.iter().zip(energy).enumerate() {
            let i = first + k;
            let e = self.wants_energy(i).then_some(e);
            self.record(i, m, e)?;
        }
        Ok(())
    }
}

/// Every trace row in memory (tests, the report).
#[derive(Debug, Clone, Default)]
pub struct TraceRows {
    /// Sample rate \[Hz\] (row `i` is time `i / rate_hz`).
    pub rate_hz: f64,
    /// The rows (of a several-contact render: contact 0's motion and the
    /// total energy).
    pub rows: Vec<TraceRow>,
    /// The further contacts' motion of a several-contact render,
    /// `contacts - 1` per row (contact 1 first).
    pub further: Vec<Motion>,
    /// Contacts per row (1 for one contact).
    pub contacts: usize,
}

impl TraceSink for TraceRows {
    fn wants_energy(&self, _: usize) -> bool {
        true
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        self.rows.push(TraceRow {
            t: i as f64 / self.rate_hz,
            obs: m.with_energy(e.expect("every energy was asked for")),
            surface: [0.0; 2],
        });
        Ok(())
    }
    fn record_driven(
        &mut self,
        i: usize,
        m: &Motion,
        e: Option<f64>,
        surface: [f64; 2],
    ) -> std::io::Result<()> {
        self.record(i, m, e)?;
        if let Some(r) = self.rows.last_mut() {
            r.surface = surface;
        }
        Ok(())
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        check_contacts(motions, self.contacts)?;
        self.further.extend_from_slice(&motions[1..]);
        self.record(i, &motions[0], e)
    }
}

/// An error unless a sample holds the `contacts` motions a sink was made
/// for.
pub(super) fn check_contacts(motions: &[Motion], contacts: usize) -> std::io::Result<()> {
    if motions.len() == contacts {
        Ok(())
    } else {
        Err(std::io::Error::other(format!(
            "a trace of {contacts} contacts was handed {} motions",
            motions.len()
        )))
    }
}

/// Two sinks fed the same samples (e.g. the CSV file and the plot).
impl<A: TraceSink, B: TraceSink> TraceSink for (A, B) {
    fn wants_energy(&self, i: usize) -> bool {
        self.0.wants_energy(i) || self.1.wants_energy(i)
    }
    fn every_energy(&self) -> bool {
        self.0.every_energy() || self.1.every_energy()
    }
    fn needs_ticks(&self) -> bool {
        self.0.needs_ticks() || self.1.needs_ticks()
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        let e0 = if self.0.wants_energy(i) { e } else { None };
        let e1 = if self.1.wants_energy(i) { e } else { None };
        self.0.record(i, m, e0)?;
        self.1.record(i, m, e1)
    }
    fn record_driven(
        &mut self,
        i: usize,
        m: &Motion,
        e: Option<f64>,
        surface: [f64; 2],
    ) -> std::io::Result<()> {
        let e0 = if self.0.wants_energy(i) { e } else { None };
        let e1 = if self.1.wants_energy(i) { e } else { None };
        self.0.record_driven(i, m, e0, surface)?;
        self.1.record_driven(i, m, e1, surface)
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        let e0 = if self.0.wants_energy(i) { e } else { None };
        let e1 = if self.1.wants_energy(i) { e } else { None };
        self.0.record_several(i, motions, e0)?;
        self.1.record_several(i, motions, e1)
    }
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        self.0.record_run(first, motion, energy)?;
        self.1.record_run(first, motion, energy)
    }
}
