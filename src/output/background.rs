//! [`BackgroundWriter`]: an [`OutputWriter`] on a thread of its own, so that a run's next step
//! goes on while a frame is compressed and written.
//!
//! A frame is copied (a few hundred kilobytes at 1e4 elements: well under a millisecond) and
//! handed over through a queue of about [`QUEUED_BYTES`] of frames; when the writer falls
//! further behind, the run waits for it, so memory stays bounded. Everything the writer does
//! stays as on one thread: the same frames and `/stats` rows in the same order, the same
//! commits, and on an error or a dropped writer, the frames already handed over are written and
//! committed first (what the writer's own drop does). A writer error reaches the run at its
//! next frame, stats batch or `finish`. A frame written in blocks ([`OutputWriter::begin_frame`])
//! is handed over block by block, each at most 8 MiB of values, so the queue then holds at
//! most its length in blocks.

use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

use super::{
    invalid, Field, Frame, FrameLayout, FrameOptions, OutputError, OutputWriter, StepStats,
};
use crate::fracture::cracks::CrackSurface;

/// Bytes of frames the run may be ahead of the writer before it waits (estimated from the
/// mesh's size, see [`queue_length`]): enough for the writer to catch up on the other core
/// after a commit, without holding much of the run in memory.
pub const QUEUED_BYTES: usize = 64 << 20;

/// Frames queued at most, however small.
const MAX_QUEUED_FRAMES: usize = 256;

/// Frames the run may be ahead of the writer, for `nodes` and `elements`: [`QUEUED_BYTES`]
/// over an upper estimate of a frame's size (12 doubles a node — positions, velocities,
/// displacement and a carried field —, 20 an element — the stress, its derived copies and
/// the history), at least 2.
pub fn queue_length(nodes: usize, elements: usize) -> usize {
    let frame = 8 * (12 * nodes + 20 * elements) + 4096;
    (QUEUED_BYTES / frame).clamp(2, MAX_QUEUED_FRAMES)
}

/// `/stats` rows handed over in one batch when no frame takes them sooner.
const STATS_BATCH: usize = 256;

/// A field owned by the queue.
struct OwnedField {
    name: String,
    cols: usize,
    data: Vec<f64>,
}

impl OwnedField {
    fn copy(fields: &[Field]) -> Vec<Self> {
        (fields.iter())
            .map(|f| OwnedField {
                name: f.name.into(),
                cols: f.cols,
                data: f.data.to_vec(),
            })
            .collect()
    }

    fn borrow(fields: &[Self]) -> Vec<Field<'_>> {
        (fields.iter())
            .map(|f| Field {
                name: &f.name,
                cols: f.cols,
                data: &f.data,
            })
            .collect()
    }
}

/// A [`Frame`] owned by the queue.
struct OwnedFrame {
    step: u64,
    time: f64,
    positions: Vec<[f64; 3]>,
    velocities: Vec<[f64; 3]>,
    rest_positions: Vec<[f64; 3]>,
    tets: Vec<[usize; 4]>,
    topology_changed: bool,
    stress: Vec<[f64; 6]>,
    element_fields: Vec<OwnedField>,
    node_fields: Vec<OwnedField>,
    row_fields: Vec<OwnedField>,
    attributes: Vec<(String, f64)>,
    cracks: Option<CrackSurface>,
}

impl OwnedFrame {
    fn copy(f: &Frame) -> Self {
        OwnedFrame {
            step: f.step,
            time: f.time,
            positions: f.positions.to_vec(),
            velocities: f.velocities.to_vec(),
            rest_positions: f.rest_positions.to_vec(),
            tets: f.tets.to_vec(),
            topology_changed: f.topology_changed,
            stress: f.stress.to_vec(),
            element_fields: OwnedField::copy(f.element_fields),
            node_fields: OwnedField::copy(f.node_fields),
            row_fields: OwnedField::copy(f.row_fields),
            attributes: (f.attributes.iter())
                .map(|(name, value)| (name.to_string(), *value))
                .collect(),
            cracks: f.cracks.cloned(),
        }
    }

    /// Writes the frame with `writer`.
    fn write(&self, writer: &mut OutputWriter) -> Result<(), OutputError> {
        let attributes: Vec<(&str, f64)> = (self.attributes.iter())
            .map(|(name, value)| (name.as_str(), *value))
            .collect();
        writer.write_frame(&Frame {
            step: self.step,
            time: self.time,
            positions: &self.positions,
            velocities: &self.velocities,
            rest_positions: &self.rest_positions,
            tets: &self.tets,
            topology_changed: self.topology_changed,
            stress: &self.stress,
            element_fields: &OwnedField::borrow(&self.element_fields),
            node_fields: &OwnedField::borrow(&self.node_fields),
            row_fields: &OwnedField::borrow(&self.row_fields),
            attributes: &attributes,
            cracks: self.cracks.as_ref(),
        })
    }
}

/// What the run hands to the writing thread.
enum Job {
    /// `/stats` rows, then a frame.
    Frame(Vec<StepStats>, Box<OwnedFrame>),
    /// `/stats` rows, then the beginning of a frame written in blocks.
    Begin(Vec<StepStats>, Box<FrameLayout>),
    /// A block of rows of a frame's dataset: its index, the first row, the values.
    Rows(usize, usize, Vec<f64>),
    /// The end of a frame written in blocks, with its crack surfaces and fields of rows.
    End(Option<Box<CrackSurface>>, Vec<OwnedField>),
    /// `/stats` rows.
    Stats(Vec<StepStats>),
    /// The last `/stats` rows: finish the file.
    Finish(Vec<StepStats>),
}

/// An [`OutputWriter`] writing on a thread of its own (see the module docs).
pub struct BackgroundWriter {
    /// `None` once the thread ended (finished, or failed and its error taken).
    queue: Option<SyncSender<Job>>,
    thread: Option<JoinHandle<Result<(), OutputError>>>,
    /// Rows not yet handed over.
    pending_stats: Vec<StepStats>,
    /// Frames in the file once every handed-over frame is written.
    frames: usize,
    options: FrameOptions,
    path: PathBuf,
}

impl BackgroundWriter {
    /// Moves `writer` to a thread of its own.
    pub fn start(writer: OutputWriter) -> Self {
        let (queue, jobs) = sync_channel(queue_length(writer.n_nodes, writer.n_elems));
        let frames = writer.frame_count();
        let options = writer.frame_options();
        let path = writer.path().to_path_buf();
        let thread = std::thread::Builder::new()
            .name("icefem-writer".into())
            .spawn(move || {
                lower_priority();
                work(writer, jobs)
            })
            .ok();
        BackgroundWriter {
            queue: thread.is_some().then_some(queue),
            thread,
            pending_stats: Vec::new(),
            frames,
            options,
            path,
        }
    }

    /// Frames in the file once the frames handed over are written.
    pub fn frame_count(&self) -> usize {
        self.frames
    }

    /// What the frames store (see [`OutputWriter::set_frame_options`]).
    pub fn frame_options(&self) -> FrameOptions {
        self.options
    }

    /// Hands a copy of `frame` (and the `/stats` rows before it) to the writing thread; waits
    /// while the queue is full. An error the thread met is returned here.
    pub fn write_frame(&mut self, frame: &Frame) -> Result<(), OutputError> {
        let stats = std::mem::take(&mut self.pending_stats);
        self.send(Job::Frame(stats, Box::new(OwnedFrame::copy(frame))))?;
        self.frames += 1;
        Ok(())
    }

    /// Hands the beginning of a frame written in blocks to the writing thread
    /// ([`OutputWriter::begin_frame`]), with the `/stats` rows before it.
    pub fn begin_frame(&mut self, frame: &FrameLayout) -> Result<(), OutputError> {
        let stats = std::mem::take(&mut self.pending_stats);
        self.send(Job::Begin(stats, Box::new(frame.clone())))
    }

    /// Hands a block of rows of the open frame's dataset `column` to the writing thread
    /// ([`OutputWriter::write_rows`]); waits while the queue is full.
    pub fn write_rows(
        &mut self,
        column: usize,
        first: usize,
        values: Vec<f64>,
    ) -> Result<(), OutputError> {
        self.send(Job::Rows(column, first, values))
    }

    /// Completes the open frame with its crack surfaces `cracks` (fracture runs) and fields
    /// of rows `row_fields` ([`OutputWriter::end_frame`]).
    pub fn end_frame(
        &mut self,
        cracks: Option<CrackSurface>,
        row_fields: &[Field],
    ) -> Result<(), OutputError> {
        let rows = OwnedField::copy(row_fields);
        self.send(Job::End(cracks.map(Box::new), rows))?;
        self.frames += 1;
        Ok(())
    }

    /// Appends one row to `/stats` (handed over with the next frame, or in batches).
    pub fn append_stats(&mut self, s: &StepStats) -> Result<(), OutputError> {
        self.pending_stats.push(*s);
        if self.pending_stats.len() >= STATS_BATCH {
            let stats = std::mem::take(&mut self.pending_stats);
            self.send(Job::Stats(stats))?;
        }
        Ok(())
    }

    /// Waits for every frame to be written, then finishes the file
    /// ([`OutputWriter::finish`]).
    pub fn finish(mut self) -> Result<(), OutputError> {
        let stats = std::mem::take(&mut self.pending_stats);
        self.send(Job::Finish(stats))?;
        self.queue = None;
        self.join()
    }

    fn send(&mut self, job: Job) -> Result<(), OutputError> {
        let sent = match &self.queue {
            Some(queue) => queue.send(job).is_ok(),
            None => false,
        };
        if sent {
            return Ok(());
        }
        // The thread ended early: it failed (or never started).
        self.queue = None;
        self.join()?;
        Err(invalid(&self.path, "the writing thread stopped"))
    }

    /// Waits for the thread to end; its error, if it failed.
    fn join(&mut self) -> Result<(), OutputError> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err(invalid(&self.path, "the writing thread panicked")),
            None => Err(invalid(&self.path, "the writing thread did not start")),
        }
    }
}

impl Drop for BackgroundWriter {
    /// Hands over the rows not written yet and waits for the thread: it writes what it was
    /// given and drops its writer, which commits (see [`OutputWriter`]).
    fn drop(&mut self) {
        if let Some(queue) = self.queue.take() {
            let stats = std::mem::take(&mut self.pending_stats);
            let _ = queue.send(Job::Stats(stats));
            drop(queue);
            let _ = self.join();
        }
    }
}

/// Lowers the calling thread's scheduling priority (nice 10, best effort): on a machine whose
/// cores the steps keep busy, the writer takes the time they leave, and the queue lets it
/// catch up.
fn lower_priority() {
    // SAFETY: setpriority on this thread's own id; failure leaves the priority as it was.
    unsafe {
        let tid = libc::gettid();
        libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, 10);
    }
}

/// The writing thread: does each job in order; on an error, stops (dropping `writer`, which
/// commits what it wrote) and returns it.
fn work(mut writer: OutputWriter, jobs: Receiver<Job>) -> Result<(), OutputError> {
    let append = |writer: &mut OutputWriter, rows: Vec<StepStats>| {
        rows.iter().try_for_each(|row| writer.append_stats(row))
    };
    // The loop ends when the run drops its end of the queue without finishing.
    for job in jobs {
        match job {
            Job::Frame(rows, frame) => {
                append(&mut writer, rows)?;
                frame.write(&mut writer)?;
            }
            Job::Begin(rows, frame) => {
                append(&mut writer, rows)?;
                writer.begin_frame(&frame)?;
            }
            Job::Rows(column, first, values) => writer.write_rows(column, first, &values)?,
            Job::End(cracks, rows) => {
                writer.end_frame(cracks.as_deref(), &OwnedField::borrow(&rows))?
            }
            Job::Stats(rows) => append(&mut writer, rows)?,
            Job::Finish(rows) => {
                append(&mut writer, rows)?;
                return writer.finish();
            }
        }
    }
    Ok(())
}
