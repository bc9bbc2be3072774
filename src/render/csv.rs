//! The trace CSV (docs/design.md, "The render command and the trace
//! CSV"): [`CsvTrace`], written as the render goes by formatting threads
//! and a writer thread, and [`write_trace_csv`] for rows in memory.

use super::numbers::{put_numbers, NUMBER_ROOM};
use super::trace::{check_contacts, trace_header_with, TraceRow, TraceSink, TRACE_HEADER};
use super::writer::{join_writer, spawn_ordered_writer, ChunkQueue};
use crate::engine::Motion;
use crate::scene::MAX_SPRINGS;
use std::io::Write;

/// Rows per chunk a [`CsvTrace`] hands to its formatting threads.
pub(super) const CSV_CHUNK_ROWS: usize = 4096;
/// Chunks waiting for a formatting thread (memory stays O(chunk) for any
/// length: at most this many, plus one per formatting thread, plus as many
/// formatted ones waiting for their turn to be written).
pub(super) const CSV_CHUNKS_IN_FLIGHT: usize = 4;
/// Most formatting threads of one [`CsvTrace`].
const CSV_MAX_FORMATTERS: usize = 4;

/// A chunk of rows and its place in the file.
type Chunk = (u64, Vec<TraceRow>);

/// Writes the trace CSV as it goes (docs/design.md, "The render command and
/// the trace CSV"): the render hands rows in chunks of `CSV_CHUNK_ROWS`
/// (4096) to formatting threads (one per core, at most
/// `CSV_MAX_FORMATTERS`), which turn them into text side by side, and a
/// writer thread writes the texts in the chunks' order. The text is the
/// CSV's largest cost, so it runs beside the engine on every core; O(1)
/// memory for any length, the bytes those of writing the rows in order on
/// one thread.
pub struct CsvTrace<W: Write + Send + 'static> {
    rate_hz: f64,
    /// Contacts per sample: a sample is this many consecutive entries of
    /// `rows` (contact 0's with the energy, then the further contacts').
    contacts: usize,
    /// A driven scene's trace: every row ends with the surface's columns
    /// ([`super::DRIVE_COLUMNS`]), fed by [`TraceSink::record_driven`].
    driven: bool,
    rows: Vec<TraceRow>,
    queue: ChunkQueue<TraceRow>,
    formatters: Vec<std::thread::JoinHandle<()>>,
    writer: Option<std::thread::JoinHandle<std::io::Result<W>>>,
}

impl<W: Write + Send + 'static> CsvTrace<W> {
    /// Write the header to `out` and return the sink (its threads started:
    /// one formatting thread per core, at most `CSV_MAX_FORMATTERS`).
    pub fn new(rate_hz: f64, out: W) -> std::io::Result<Self> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Self::with_formatters(rate_hz, out, cores.min(CSV_MAX_FORMATTERS))
    }

    /// [`new`](Self::new) with `formatters` formatting threads (at least 1).
    pub fn with_formatters(rate_hz: f64, out: W, formatters: usize) -> std::io::Result<Self> {
        Self::start(rate_hz, out, formatters, 1, false)
    }

    /// The trace of a driven scene (one contact; columns [`TRACE_HEADER`]
    /// then [`super::DRIVE_COLUMNS`]), fed by [`TraceSink::record_driven`].
    pub fn driven(rate_hz: f64, out: W) -> std::io::Result<Self> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Self::start(rate_hz, out, cores.min(CSV_MAX_FORMATTERS), 1, true)
    }

    /// The trace of a render of `contacts` contacts (columns
    /// [`super::trace_header`]), fed by [`TraceSink::record_several`].
    pub fn with_contacts(rate_hz: f64, out: W, contacts: usize) -> std::io::Result<Self> {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Self::start(rate_hz, out, cores.min(CSV_MAX_FORMATTERS), contacts, false)
    }

    fn start(
        rate_hz: f64,
        mut out: W,
        formatters: usize,
        contacts: usize,
        driven: bool,
    ) -> std::io::Result<Self> {
        use crossbeam::channel::bounded;
        let contacts = contacts.clamp(1, MAX_SPRINGS);
        let driven = driven && contacts == 1;
        writeln!(out, "{}", trace_header_with(contacts, driven))?;
        let formatters = formatters.max(1);
        let (to_format, chunks) = bounded::<Chunk>(CSV_CHUNKS_IN_FLIGHT);
        let (to_writer, texts) = bounded::<(u64, Vec<u8>)>(CSV_CHUNKS_IN_FLIGHT);
        let (give_rows, spare) = bounded(CSV_CHUNKS_IN_FLIGHT + formatters + 1);
        let (give_text, spare_text) = bounded::<Vec<u8>>(2 * CSV_CHUNKS_IN_FLIGHT + formatters + 1);
        let mut threads = Vec::with_capacity(formatters);
        for k in 0..formatters {
            let (chunks, to_writer) = (chunks.clone(), to_writer.clone());
            let (give_rows, spare_text) = (give_rows.clone(), spare_text.clone());
            threads.push(
                std::thread::Builder::new()
                    .name(format!("trace-csv-format-{k}"))
                    .spawn(move || {
                        for (seq, mut rows) in chunks {
                            // a spare text keeps its length: only what
                            // this chunk may need beyond it is zeroed
                            let mut text = spare_text.try_recv().unwrap_or_default();
                            text.resize(rows.len() * ROW_ROOM, 0);
                            let mut end = 0;
                            if driven {
                                for r in &rows {
                                    end = put_driven_row(&mut text, end, r);
                                }
                            } else if contacts == 1 {
                                for r in &rows {
                                    end = put_row(&mut text, end, r);
                                }
                            } else {
                                for sample in rows.chunks(contacts) {
                                    end = put_sample(&mut text, end, sample);
                                }
                            }
                            text.truncate(end);
                            rows.clear();
                            let _ = give_rows.try_send(rows);
                            if to_writer.send((seq, text)).is_err() {
                                // the writer stopped (a failed write)
                                return;
                            }
                        }
                    })?,
            );
        }
        drop((to_writer, chunks, give_rows, spare_text));
        // texts arrive in any order: the writer takes each at its turn
        let writer = spawn_ordered_writer("trace-csv-write", out, texts, give_text)?;
        Ok(Self {
            rate_hz,
            contacts,
            driven,
            rows: Vec::with_capacity(CSV_CHUNK_ROWS * contacts),
            queue: ChunkQueue {
                seq: 0,
                to: Some(to_format),
                spare,
            },
            formatters: threads,
            writer: Some(writer),
        })
    }

    /// Hand the rows so far to the formatting threads; an error if the
    /// writer has stopped (a failed write: [`finish`](Self::finish) returns
    /// it).
    fn send(&mut self) -> std::io::Result<()> {
        self.queue
            .send(&mut self.rows, CSV_CHUNK_ROWS * self.contacts)
    }

    /// Stop the threads and wait for them: the writer's result, or an error
    /// if a thread panicked.
    fn join(&mut self) -> std::io::Result<W> {
        self.queue.close();
        let mut panicked = false;
        for t in self.formatters.drain(..) {
            panicked |= t.join().is_err();
        }
        let written = join_writer(&mut self.writer);
        if panicked {
            return Err(std::io::Error::other("a trace formatting thread panicked"));
        }
        written
    }

    /// Write the remaining rows, wait for the threads, flush and hand back
    /// the writer (or the first write error).
    pub fn finish(mut self) -> std::io::Result<W> {
        let sent = if self.rows.is_empty() {
            Ok(())
        } else {
            self.send()
        };
        let out = self.join()?;
        sent.map(|_| out)
    }
}

impl<W: Write + Send + 'static> Drop for CsvTrace<W> {
    fn drop(&mut self) {
        // a sink dropped without `finish` (an error elsewhere): stop the
        // threads and wait for them, so none outlives the render
        if self.writer.is_some() {
            let _ = self.join();
        }
    }
}

impl<W: Write + Send + 'static> TraceSink for CsvTrace<W> {
    fn wants_energy(&self, _: usize) -> bool {
        true
    }
    fn needs_ticks(&self) -> bool {
        false
    }
    fn record(&mut self, i: usize, m: &Motion, e: Option<f64>) -> std::io::Result<()> {
        self.record_several(i, std::slice::from_ref(m), e)
    }
    fn record_driven(
        &mut self,
        i: usize,
        m: &Motion,
        e: Option<f64>,
        surface: [f64; 2],
    ) -> std::io::Result<()> {
        self.driven_row(i, m, e, surface)
    }
    fn record_several(
        &mut self,
        i: usize,
        motions: &[Motion],
        e: Option<f64>,
    ) -> std::io::Result<()> {
        check_contacts(motions, self.contacts)?;
        if self.driven {
            return Err(std::io::Error::other(
                "a driven scene's trace was handed a sample without its surface",
            ));
        }
        let t = i as f64 / self.rate_hz;
        let e = e.expect("every energy was asked for");
        // the further contacts ride in rows of their own (their energy
        // unused): a sample is `contacts` consecutive rows
        self.rows.extend(motions.iter().map(|m| TraceRow {
            t,
            obs: m.with_energy(e),
            surface: [0.0; 2],
        }));
        if self.rows.len() >= CSV_CHUNK_ROWS * self.contacts {
            self.send()?;
        }
        Ok(())
    }
}

impl<W: Write + Send + 'static> CsvTrace<W> {
    fn driven_row(
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
        self.rows.push(TraceRow {
            t: i as f64 / self.rate_hz,
            obs: m.with_energy(e.expect("every energy was asked for")),
            surface,
        });
        if self.rows.len() >= CSV_CHUNK_ROWS {
            self.send()?;
        }
        Ok(())
    }
}

/// Write trace rows as CSV (each number's shortest round-trip digits,
/// [`put_numbers`]).
pub fn write_trace_csv<W: Write>(rows: &[TraceRow], mut w: W) -> std::io::Result<()> {
    writeln!(w, "{TRACE_HEADER}")?;
    let mut buf = Vec::with_capacity(ROW_ROOM);
    for r in rows {
        buf.clear();
        push_row(&mut buf, r);
        w.write_all(&buf)?;
    }
    Ok(())
}

/// Room for one row in [`put_row`] or [`put_driven_row`]: 8 numbers, each
/// with its separator (the `in_contact` flag is part of one).
const ROW_ROOM: usize = 8 * NUMBER_ROOM;

/// Append one CSV row to `buf` (numbers as [`put_numbers`] writes them).
fn push_row(buf: &mut Vec<u8>, r: &TraceRow) {
    let at = buf.len();
    buf.resize(at + ROW_ROOM, 0);
    let end = put_row(buf, at, r);
    buf.truncate(end);
}

/// Write one CSV row to `out[at..]` (room for [`ROW_ROOM`] bytes); the end.
fn put_row(out: &mut [u8], at: usize, r: &TraceRow) -> usize {
    let o = &r.obs;
    let xs = [
        r.t,
        o.x_hammer,
        o.v_hammer,
        o.x_contact,
        o.v_contact,
        o.energy,
    ];
    put_numbers(out, at, &xs, |k| match k {
        4 if o.in_contact => b",1,",
        4 => b",0,",
        5 => b"\n",
        _ => b",",
    })
}

/// Write one row of a driven scene's trace to `out[at..]` (room for
/// [`ROW_ROOM`] bytes): [`put_row`]'s numbers, then the path position and
/// the surface's height ([`super::DRIVE_COLUMNS`]); the end.
fn put_driven_row(out: &mut [u8], at: usize, r: &TraceRow) -> usize {
    let o = &r.obs;
    let xs = [
        r.t,
        o.x_hammer,
        o.v_hammer,
        o.x_contact,
        o.v_contact,
        o.energy,
        r.surface[0],
        r.surface[1],
    ];
    put_numbers(out, at, &xs, |k| match k {
        4 if o.in_contact => b",1,",
        4 => b",0,",
        7 => b"\n",
        _ => b",",
    })
}

/// Write one sample of a several-contact trace to `out[at..]` (room for
/// [`ROW_ROOM`] bytes per entry of `sample`): contact 0's row as
/// [`put_row`] writes it (its `energy` the total), then each further
/// contact's `x_hammer, v_hammer, x_contact, v_contact, in_contact`
/// ([`trace_header`]); the end.
fn put_sample(out: &mut [u8], at: usize, sample: &[TraceRow]) -> usize {
    let (r, further) = (&sample[0], &sample[1..]);
    let o = &r.obs;
    let xs = [
        r.t,
        o.x_hammer,
        o.v_hammer,
        o.x_contact,
        o.v_contact,
        o.energy,
    ];
    let mut at = put_numbers(out, at, &xs, |k| match k {
        4 if o.in_contact => b",1,",
        4 => b",0,",
        _ => b",",
    });
    for (j, f) in further.iter().enumerate() {
        let (m, last) = (&f.obs, j + 1 == further.len());
        let xs = [m.x_hammer, m.v_hammer, m.x_contact, m.v_contact];
        at = put_numbers(out, at, &xs, |k| match (k, m.in_contact, last) {
            (3, true, true) => b",1\n",
            (3, false, true) => b",0\n",
            (3, true, false) => b",1,",
            (3, false, false) => b",0,",
            _ => b",",
        });
    }
    at
}
