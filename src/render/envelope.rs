//! The plot's input (docs/design.md, "Offline rendering"): min/max per
//! bucket of at most [`ENVELOPE_BUCKETS`] buckets and the energy at the
//! bucket ends.

use super::trace::TraceSink;
use crate::engine::Motion;

/// Largest number of buckets of a [`TraceEnvelope`].
pub const ENVELOPE_BUCKETS: usize = 1024;

/// One bucket of consecutive samples of a [`TraceEnvelope`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvelopeBucket {
    /// First sample.
    pub start: usize,
    /// Samples in the bucket.
    pub len: usize,
    /// Smallest and largest hammer height \[m\].
    pub x_hammer: [f64; 2],
    /// Smallest and largest contact-point displacement \[m\].
    pub x_contact: [f64; 2],
    /// Some sample of the bucket is in contact.
    pub in_contact: bool,
    /// Energy at the bucket's last sample \[J\] (total energy does not
    /// increase, so it is the bucket's smallest and the next one's start).
    pub energy_end: f64,
}

/// The plot's input: min/max per bucket of at most [`ENVELOPE_BUCKETS`]
/// buckets, whatever the length, and the energy at the bucket ends only,
/// so a 10-minute render costs the plot what a 1-second one does.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceEnvelope {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Samples per bucket (the last may be shorter).
    pub bucket_len: usize,
    /// Samples the render will have.
    pub samples: usize,
    /// Energy at sample 0 \[J\].
    pub energy_start: f64,
    /// The buckets so far.
    pub buckets: Vec<EnvelopeBucket>,
}

impl TraceEnvelope {
    /// An empty envelope for a render of `samples` samples.
    pub fn new(rate_hz: f64, samples: usize) -> Self {
        Self {
            rate_hz,
            bucket_len: samples.div_ceil(ENVELOPE_BUCKETS).max(1),
            samples,
            energy_start: f64::NAN,
            buckets: Vec::with_capacity(ENVELOPE_BUCKETS),
        }
    }

    fn is_bucket_end(&self, i: usize) -> bool {
        (i + 1).is_multiple_of(self.bucket_len) || i + 1 == self.samples
    }
}

impl TraceSink for TraceEnvelope {
    fn wants_energy(&self, i: usize) -> bool {
        i == 0 || self.is_bucket_end(i)
    }
    /// The plot draws the hammer relative to the surface (what the contact
    /// sees), not the surface.
    fn record_driven(
        &mut self,
        i: usize,
        m: &Motion,
        e: Option<f64>,
        _: [f64; 2],
    ) -> std::io::Result<()> {
        self.record(i, m, e)
    }
    fn every_energy(&self) -> bool {
        false
    }
    fn needs_ticks(&self) -> bool {
        false
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        if i == 0 {
            self.energy_start = e.expect("asked for");
        }
        if i.is_multiple_of(self.bucket_len) {
            self.buckets.push(EnvelopeBucket {
                start: i,
                len: 0,
                x_hammer: [m.x_hammer; 2],
                x_contact: [m.x_contact; 2],
                in_contact: false,
                energy_end: f64::NAN,
            });
        }
        let end = self.is_bucket_end(i);
        let b = self
            .buckets
            .last_mut()
            .expect("a bucket starts at sample 0");
        b.len += 1;
        b.x_hammer = [b.x_hammer[0].min(m.x_hammer), b.x_hammer[1].max(m.x_hammer)];
        b.x_contact = [
            b.x_contact[0].min(m.x_contact),
            b.x_contact[1].max(m.x_contact),
        ];
        b.in_contact |= m.in_contact;
        if end {
            b.energy_end = e.expect("asked for");
        }
        Ok(())
    }
    /// Contact 0's hammer and point, shaded where any contact is closed.
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        let m = Motion {
            in_contact: motions.iter().any(|m| m.in_contact),
            ..motions[0]
        };
        self.record(i, &m, e)
    }
    /// [`record`](Self::record) for a run of samples, a bucket's share at
    /// a time (the same min/max in the same order).
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        let n = motion.len().min(energy.len());
        let mut k = 0;
        while k < n {
            let i = first + k;
            if i.is_multiple_of(self.bucket_len) {
                // a bucket starts (and may end, or be the render's first)
                let e = self.wants_energy(i).then_some(energy[k]);
                self.record(i, &motion[k], e)?;
                k += 1;
                continue;
            }
            // the rest of this bucket within the run
            let span = (self.bucket_len - i % self.bucket_len).min(n - k);
            let end = self.is_bucket_end(i + span - 1);
            let b = self
                .buckets
                .last_mut()
                .expect("a bucket starts at sample 0");
            for m in &motion[k..k + span] {
                b.x_hammer = [b.x_hammer[0].min(m.x_hammer), b.x_hammer[1].max(m.x_hammer)];
                b.x_contact = [
                    b.x_contact[0].min(m.x_contact),
                    b.x_contact[1].max(m.x_contact),
                ];
                b.in_contact |= m.in_contact;
            }
            b.len += span;
            if end {
                b.energy_end = energy[k + span - 1];
            }
            k += span;
        }
        Ok(())
    }
}
