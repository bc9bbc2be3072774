//! The trace as a NumPy `.npy` file (docs/design.md, "The render command
//! and the trace CSV"): the CSV's columns as named f64 fields, the
//! numbers' own bits.

use super::csv::{CSV_CHUNKS_IN_FLIGHT, CSV_CHUNK_ROWS};
use super::trace::{check_contacts, trace_header_with, TraceRow, TraceSink};
use super::writer::{join_writer, spawn_ordered_writer, ChunkQueue};
use crate::engine::Motion;
use crate::scene::MAX_SPRINGS;
use std::io::Write;

/// The NPY header (format 1.0) of `rows` records whose fields are the
/// comma-separated `columns` (the CSV's header), each a little-endian f64
/// (`in_contact` 0 or 1).
fn npy_header_with(columns: &str, rows: usize) -> Vec<u8> {
    let fields: Vec<String> = columns
        .split(',')
        .map(|name| format!("('{name}', '<f8')"))
        .collect();
    let dict = format!(
        "{{'descr': [{}], 'fortran_order': False, 'shape': ({rows},), }}",
        fields.join(", ")
    );
    // magic, version 1.0, header length; the whole header padded with
    // spaces to a multiple of 64 bytes and ended by a newline
    let unpadded = 10 + dict.len() + 1;
    let pad = unpadded.next_multiple_of(64) - unpadded;
    let len = u16::try_from(dict.len() + pad + 1).expect("a short header");
    let mut h = b"\x93NUMPY\x01\x00".to_vec();
    h.extend_from_slice(&len.to_le_bytes());
    h.extend_from_slice(dict.as_bytes());
    h.extend(std::iter::repeat_n(b' ', pad));
    h.push(b'\n');
    h
}

/// Bytes of one NPY trace record (7 f64 fields).
const NPY_RECORD: usize = 56;
/// Bytes a further contact adds to a record (5 f64 fields).
const NPY_FURTHER: usize = 40;

/// Writes the trace as a NumPy `.npy` file (docs/design.md, "The render
/// command and the trace CSV"): one record per sample with the CSV's
/// columns as named f64 fields, the numbers' own bits (no text), so
/// `numpy.load(path)["energy"]` reads a column exactly. The row count is
/// in the header, so the render's length is given up front;
/// [`finish`](Self::finish) checks that every row came. The records are
/// written by a writer thread in chunks of `CSV_CHUNK_ROWS` (the file
/// system's copy runs beside the engine).
pub struct NpyTrace<W: Write + Send + 'static> {
    rate_hz: f64,
    /// Contacts per record ([`super::trace_header`]).
    contacts: usize,
    /// A driven scene's trace: each record ends with the surface's two
    /// fields ([`super::DRIVE_COLUMNS`]), fed by
    /// [`TraceSink::record_driven`].
    driven: bool,
    /// Bytes handed to the writer at a time (whole records).
    chunk: usize,
    rows: usize,
    written: usize,
    buf: Vec<u8>,
    queue: ChunkQueue<u8>,
    writer: Option<std::thread::JoinHandle<std::io::Result<W>>>,
}

impl<W: Write + Send + 'static> NpyTrace<W> {
    /// Bytes per record of one contact (7 f64 fields).
    pub const RECORD: usize = NPY_RECORD;

    /// Write the header for `rows` records to `out` and start the writer.
    pub fn new(rate_hz: f64, rows: usize, out: W) -> std::io::Result<Self> {
        Self::with_contacts(rate_hz, rows, 1, out)
    }

    /// The trace of a render of `contacts` contacts: the fields of
    /// [`super::trace_header`], [`Self::RECORD`] bytes for contact 0 and 40 more
    /// per further contact; fed by [`TraceSink::record_several`].
    pub fn with_contacts(
        rate_hz: f64,
        rows: usize,
        contacts: usize,
        out: W,
    ) -> std::io::Result<Self> {
        Self::start(rate_hz, rows, contacts, false, out)
    }

    /// The trace of a driven scene (one contact): the fields of
    /// [`super::TRACE_HEADER`] then [`super::DRIVE_COLUMNS`], 72 bytes per
    /// record; fed by [`TraceSink::record_driven`].
    pub fn driven(rate_hz: f64, rows: usize, out: W) -> std::io::Result<Self> {
        Self::start(rate_hz, rows, 1, true, out)
    }

    fn start(
        rate_hz: f64,
        rows: usize,
        contacts: usize,
        driven: bool,
        mut out: W,
    ) -> std::io::Result<Self> {
        use crossbeam::channel::bounded;
        let contacts = contacts.clamp(1, MAX_SPRINGS);
        let driven = driven && contacts == 1;
        out.write_all(&npy_header_with(&trace_header_with(contacts, driven), rows))?;
        let chunk = CSV_CHUNK_ROWS
            * (NPY_RECORD + NPY_FURTHER * (contacts - 1) + if driven { 16 } else { 0 });
        let (to_writer, chunks) = bounded(CSV_CHUNKS_IN_FLIGHT);
        let (give, spare) = bounded(CSV_CHUNKS_IN_FLIGHT + 1);
        let writer = spawn_ordered_writer("trace-npy-write", out, chunks, give)?;
        Ok(Self {
            rate_hz,
            contacts,
            driven,
            chunk,
            rows,
            written: 0,
            buf: Vec::with_capacity(chunk),
            queue: ChunkQueue {
                seq: 0,
                to: Some(to_writer),
                spare,
            },
            writer: Some(writer),
        })
    }

    /// Hand the records so far to the writer; an error if it has stopped
    /// (a failed write: [`finish`](Self::finish) returns it).
    fn send(&mut self) -> std::io::Result<()> {
        self.queue.send(&mut self.buf, self.chunk)
    }

    /// Stop the writer and wait for it: its result, or an error if it
    /// panicked.
    fn join(&mut self) -> std::io::Result<W> {
        self.queue.close();
        join_writer(&mut self.writer)
    }

    /// Write the remaining records, wait for the writer, flush and hand
    /// back the output; an error if a write failed, or if fewer or more
    /// records came than the header says.
    pub fn finish(mut self) -> std::io::Result<W> {
        let sent = if self.buf.is_empty() {
            Ok(())
        } else {
            self.send()
        };
        let out = self.join()?;
        sent?;
        if self.written != self.rows {
            return Err(std::io::Error::other(format!(
                "the trace's header says {} rows, {} were recorded",
                self.rows, self.written
            )));
        }
        Ok(out)
    }

    fn push(&mut self, i: usize, m: &Motion, e: f64) {
        let row = TraceRow {
            t: i as f64 / self.rate_hz,
            obs: m.with_energy(e),
            surface: [0.0; 2],
        };
        let mut rec = [0u8; NPY_RECORD];
        for (k, x) in row.columns().into_iter().enumerate() {
            rec[8 * k..8 * k + 8].copy_from_slice(&x.to_le_bytes());
        }
        self.buf.extend_from_slice(&rec);
    }
}

impl<W: Write + Send + 'static> NpyTrace<W> {
    /// An error if this is a driven scene's trace (its records need the
    /// surface: [`TraceSink::record_driven`]).
    fn undriven(&self) -> std::io::Result<()> {
        if self.driven {
            Err(std::io::Error::other(
                "a driven scene's trace was handed a sample without its surface",
            ))
        } else {
            Ok(())
        }
    }
}

impl<W: Write + Send + 'static> Drop for NpyTrace<W> {
    fn drop(&mut self) {
        // dropped without `finish` (an error elsewhere): stop the writer
        // and wait for it, so it does not outlive the render
        if self.writer.is_some() {
            let _ = self.join();
        }
    }
}

impl<W: Write + Send + 'static> TraceSink for NpyTrace<W> {
    fn wants_energy(&self, _: usize) -> bool {
        true
    }
    fn needs_ticks(&self) -> bool {
        false
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        self.record_several(i, std::slice::from_ref(m), e)
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        check_contacts(motions, self.contacts)?;
        self.undriven()?;
        self.push(i, &motions[0], e.expect("every energy was asked for"));
        for m in &motions[1..] {
            let flag = f64::from(u8::from(m.in_contact));
            for x in [m.x_hammer, m.v_hammer, m.x_contact, m.v_contact, flag] {
                self.buf.extend_from_slice(&x.to_le_bytes());
            }
        }
        self.written += 1;
        if self.buf.len() >= self.chunk {
            self.send()?;
        }
        Ok(())
    }
    fn record_driven(
        &mut self,
        i: usize,
        m: &Motion,
        e: Option<f64>,
        surface: [f64; 2],
    ) -> std::io::Result<()> {
        if !self.driven {
            return Err(std::io::Error::other(
                "a trace made for a scene that is not driven was handed a surface",
            ));
        }
        self.push(i, m, e.expect("every energy was asked for"));
        for x in surface {
            self.buf.extend_from_slice(&x.to_le_bytes());
        }
        self.written += 1;
        if self.buf.len() >= self.chunk {
            self.send()?;
        }
        Ok(())
    }
    fn record_run(
        &mut self,
        first: usize,
        motion: &[Motion],
        energy: &[f64],
    ) -> std::io::Result<()> {
        check_contacts(&[Motion::default()], self.contacts)?;
        self.undriven()?;
        for (k, (m, &e)) in motion.iter().zip(energy).enumerate() {
            self.push(first + k, m, e);
            if self.buf.len() >= self.chunk {
                self.send()?;
            }
        }
        self.written += motion.len().min(energy.len());
        Ok(())
    }
}
