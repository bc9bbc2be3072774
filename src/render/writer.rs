//! The threads behind the trace files: a writer thread that writes
//! numbered chunks in their order, and the queue that hands chunks on to
//! a trace's threads and takes spent buffers back.

use std::io::Write;

/// A thread that writes numbered chunks of bytes to `out` in their order
/// (they may arrive in any order), handing each written buffer back on
/// `give` for reuse; it returns `out` after a flush, or the first write
/// error, when `chunks` closes.
pub(super) fn spawn_ordered_writer<W: Write + Send + 'static>(
    name: &str,
    mut out: W,
    chunks: crossbeam::channel::Receiver<(u64, Vec<u8>)>,
    give: crossbeam::channel::Sender<Vec<u8>>,
) -> std::io::Result<std::thread::JoinHandle<std::io::Result<W>>> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let mut waiting = std::collections::BTreeMap::new();
            let mut next = 0u64;
            for (seq, bytes) in chunks {
                waiting.insert(seq, bytes);
                while let Some(bytes) = waiting.remove(&next) {
                    out.write_all(&bytes)?;
                    let _ = give.try_send(bytes);
                    next += 1;
                }
            }
            out.flush()?;
            Ok(out)
        })
}

/// Wait for a writer thread (once): its result, or an error if it panicked.
pub(super) fn join_writer<W>(
    writer: &mut Option<std::thread::JoinHandle<std::io::Result<W>>>,
) -> std::io::Result<W> {
    writer
        .take()
        .expect("joined once")
        .join()
        .map_err(|_| std::io::Error::other("the trace writer panicked"))?
}

/// The sending end of a trace's threads: hands numbered chunks on (the
/// next thread puts them back in order) and takes spent buffers back for
/// reuse.
pub(super) struct ChunkQueue<T> {
    pub(super) seq: u64,
    pub(super) to: Option<crossbeam::channel::Sender<(u64, Vec<T>)>>,
    pub(super) spare: crossbeam::channel::Receiver<Vec<T>>,
}

impl<T> ChunkQueue<T> {
    /// Hand `buf` on as the next chunk, leaving an empty buffer of
    /// `capacity` (a spare one if any) in its place; an error if the
    /// threads have stopped (a failed write: the sink's `finish` returns
    /// it).
    pub(super) fn send(&mut self, buf: &mut Vec<T>, capacity: usize) -> std::io::Result<()> {
        let mut fresh = self
            .spare
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(capacity));
        fresh.clear();
        let chunk = std::mem::replace(buf, fresh);
        let stopped = || std::io::Error::other("the trace writer stopped");
        self.to
            .as_ref()
            .ok_or_else(stopped)?
            .send((self.seq, chunk))
            .map_err(|_| stopped())?;
        self.seq += 1;
        Ok(())
    }

    /// No more chunks: the threads finish what they have and end.
    pub(super) fn close(&mut self) {
        self.to = None;
    }
}
