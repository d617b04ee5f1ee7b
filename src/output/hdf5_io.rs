//! HDF5 helpers shared by the writer, resume, the XDMF sidecar, the frame reader and
//! `describe`: error context, opening for reading, close-on-exec, attributes, matrices and index arrays (written
//! compressed when large), their shape-checked reading, the signature and layout checks, and
//! the listing of `/frames`.

use std::io::Read as _;
use std::ops::Range;
use std::path::Path;
use std::str::FromStr;

use hdf5::types::{VarLenAscii, VarLenUnicode};
use hdf5::{Dataset, File, Group, H5Type};
use ndarray::{ArrayView1, ArrayView2};

use super::{corrupt, invalid, OutputError};
use crate::fracture::cracks::CrackSurface;

/// Marks the file's descriptor close-on-exec. HDF5 opens files without `O_CLOEXEC`, so a
/// child process started while a file is open inherits the descriptor and keeps the file's lock
/// after we close it: our own next open of that file then fails with "unable to lock file"
/// (seen in the test suite, which writes files while it runs `icefem` processes). Best effort:
/// on failure the descriptor simply stays inheritable.
pub(super) fn close_on_exec(file: &File) {
    hdf5::sync::sync(|| {
        let mut handle: *mut std::ffi::c_void = std::ptr::null_mut();
        // SAFETY: `file` is an open file id; with the default (sec2) driver the VFD handle
        // points to the POSIX descriptor, an `int`. The HDF5 call runs under hdf5's lock.
        unsafe {
            let status = hdf5_sys::h5f::H5Fget_vfd_handle(
                file.id(),
                hdf5_sys::h5p::H5P_DEFAULT,
                &mut handle,
            );
            if status >= 0 && !handle.is_null() {
                let fd = *(handle as *const libc::c_int);
                libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
            }
        }
    });
}

/// Opens `path` read-only to read icefem output, with HDF5's own file lock off and the
/// descriptor close-on-exec. Who may write a file is settled by the run's lock
/// (`ownership::RunLock`), and runs write with HDF5's lock off so that readers can follow them;
/// a reader taking HDF5's lock would instead fail ("Resource temporarily unavailable") on a file
/// another program holds, or one whose lock a child process inherited.
pub(super) fn open_read(path: &Path, doing: &str) -> Result<File, OutputError> {
    let file = File::with_options()
        .with_fapl(|fapl| fapl.file_locking(false))
        .open(path)
        .ctx(path, || doing.into())?;
    close_on_exec(&file);
    Ok(file)
}

/// Target number of values per chunk of a frame dataset (64 Ki × 8 B = 512 KiB),
/// below HDF5's default 1 MiB chunk cache.
const FRAME_CHUNK_VALUES: usize = 65536;

/// Attaches the file path and a description of the failed operation to HDF5 errors.
pub(super) trait Hdf5Context<T> {
    fn ctx(self, path: &Path, context: impl FnOnce() -> String) -> Result<T, OutputError>;
}

impl<T> Hdf5Context<T> for hdf5::Result<T> {
    fn ctx(self, path: &Path, context: impl FnOnce() -> String) -> Result<T, OutputError> {
        self.map_err(|error| OutputError::Hdf5 {
            path: path.to_path_buf(),
            context: context(),
            error,
        })
    }
}

/// The gist of an HDF5 error for a message: its stack reads like "H5Fcreate(): unable to
/// create file: unable to open file: name = '…', errno = 2, error message = 'No such file or
/// directory', flags = 15, o_flags = c2" (and more); this keeps the innermost "unable to …"
/// and what follows it, with the operating system's message in place of the raw fields.
pub(super) fn concise(error: &hdf5::Error) -> String {
    let text = error.to_string();
    let text = match text.split_once("(): ") {
        Some((function, rest)) if function.starts_with("H5") && !function.contains(' ') => rest,
        _ => text.as_str(),
    };
    let segments: Vec<&str> = text.split(": ").collect();
    let innermost = segments
        .iter()
        .rposition(|s| s.starts_with("unable to"))
        .unwrap_or(0);
    segments[innermost..]
        .iter()
        .map(|s| os_message(s).unwrap_or_else(|| s.to_string()))
        .collect::<Vec<_>>()
        .join(": ")
}

/// "No such file or directory (errno 2)" from a segment holding HDF5's raw
/// "errno = 2, error message = 'No such file or directory'" fields, if it does.
fn os_message(segment: &str) -> Option<String> {
    let (_, after) = segment.split_once("error message = '")?;
    let message = after.split('\'').next()?;
    let errno = segment
        .split_once("errno = ")
        .and_then(|(_, e)| e.split(',').next());
    Some(match errno {
        Some(n) => format!("{message} (errno {n})"),
        None => message.to_string(),
    })
}

/// Runs an HDF5 C call under the library's lock; a negative status becomes the library's error.
fn h5_call(call: impl FnOnce() -> hdf5_sys::h5::herr_t) -> hdf5::Result<()> {
    let status = hdf5::sync::sync(call);
    if status < 0 {
        Err(hdf5::Error::query().unwrap_or_else(|e| e))
    } else {
        Ok(())
    }
}

/// Links `object` (an anonymous group) into `parent` as `name`: from then on it is part of the
/// file's tree.
pub(super) fn link_object(
    path: &Path,
    object: &Group,
    parent: &Group,
    name: &str,
) -> Result<(), OutputError> {
    let c_name = std::ffi::CString::new(name).map_err(|_| invalid(path, "NUL in a link name"))?;
    // SAFETY: both ids are open objects of the same file; the name is NUL-terminated.
    h5_call(|| unsafe {
        hdf5_sys::h5o::H5Olink(
            object.id(),
            parent.id(),
            c_name.as_ptr(),
            hdf5_sys::h5p::H5P_DEFAULT,
            hdf5_sys::h5p::H5P_DEFAULT,
        )
    })
    .ctx(path, || format!("linking {name} into {}", parent.name()))
}

/// Hard-links the dataset `name` of group `from` into group `to` under the same name (`from`
/// may be a group not linked into the file yet).
pub(super) fn link_dataset(
    path: &Path,
    from: &Group,
    to: &Group,
    name: &str,
) -> Result<(), OutputError> {
    let c_name = std::ffi::CString::new(name).map_err(|_| invalid(path, "NUL in a link name"))?;
    // SAFETY: both ids are open groups of the same file; the name is NUL-terminated.
    h5_call(|| unsafe {
        hdf5_sys::h5l::H5Lcreate_hard(
            from.id(),
            c_name.as_ptr(),
            to.id(),
            c_name.as_ptr(),
            hdf5_sys::h5p::H5P_DEFAULT,
            hdf5_sys::h5p::H5P_DEFAULT,
        )
    })
    .ctx(path, || format!("hard-linking {name} from {}", from.name()))
}

/// Makes an HDF5 variable-length UTF-8 string (rejects interior NULs).
pub(super) fn vlen_str(path: &Path, what: &str, s: &str) -> Result<VarLenUnicode, OutputError> {
    VarLenUnicode::from_str(s).map_err(|e| invalid(path, format!("{what}: {e}")))
}

pub(super) fn write_attr<T: H5Type>(
    path: &Path,
    loc: &hdf5::Location,
    name: &str,
    value: &T,
) -> Result<(), OutputError> {
    loc.new_attr::<T>()
        .create(name)
        .and_then(|a| a.write_scalar(value))
        .ctx(path, || {
            format!("writing attribute {name} on {}", loc.name())
        })
}

pub(super) fn read_attr<T: H5Type>(
    path: &Path,
    loc: &hdf5::Location,
    name: &str,
) -> Result<T, OutputError> {
    loc.attr(name)
        .and_then(|a| a.read_scalar::<T>())
        .ctx(path, || {
            format!("reading attribute {name} of {}", loc.name())
        })
}

/// Reads a scalar string attribute written as variable-length UTF-8 or ASCII
/// (the latter for files touched by other tools).
pub(super) fn read_string(attr: &hdf5::Attribute) -> hdf5::Result<String> {
    match attr.read_scalar::<VarLenUnicode>() {
        Ok(s) => Ok(s.as_str().to_owned()),
        Err(e) => attr
            .read_scalar::<VarLenAscii>()
            .map(|s| s.as_str().to_owned())
            .map_err(|_| e),
    }
}

pub(super) fn read_string_attr(
    path: &Path,
    loc: &hdf5::Location,
    name: &str,
) -> Result<String, OutputError> {
    loc.attr(name).and_then(|a| read_string(&a)).ctx(path, || {
        format!("reading attribute {name} of {}", loc.name())
    })
}

/// Datasets with fewer values than this are stored contiguous and uncompressed: below 16 kB
/// (of doubles) the chunk index and deflate's set-up (a few hundred kilobytes of tables per
/// dataset) cost more time than the bytes saved are worth.
const COMPRESS_MIN_VALUES: usize = 2048;

/// Writes a row-major `rows × cols` matrix (1-D when `cols == 1`), chunked and compressed
/// when it holds at least `COMPRESS_MIN_VALUES` values; returns the dataset.
pub(super) fn write_matrix<T: H5Type>(
    path: &Path,
    g: &Group,
    name: &str,
    rows: usize,
    cols: usize,
    data: &[T],
) -> Result<Dataset, OutputError> {
    let ctx = || format!("writing {}/{name} [{rows}, {cols}]", g.name());
    let mut b = g.new_dataset_builder();
    if let Some(chunk) = chunk_rows(rows, cols) {
        b = compress(match cols {
            1 => b.chunk(chunk),
            _ => b.chunk((chunk, cols)),
        });
    }
    if cols == 1 {
        b.with_data(ArrayView1::from(data))
            .create(name)
            .ctx(path, ctx)
    } else {
        let view = ArrayView2::from_shape((rows, cols), data)
            .map_err(|e| invalid(path, format!("{name}: {e}")))?;
        b.with_data(view).create(name).ctx(path, ctx)
    }
}

/// Rows per chunk of a frame dataset of `rows` × `cols` values; `None` when it is stored
/// contiguous and uncompressed (fewer than `COMPRESS_MIN_VALUES` values).
pub(super) fn chunk_rows(rows: usize, cols: usize) -> Option<usize> {
    (rows * cols >= COMPRESS_MIN_VALUES).then(|| (FRAME_CHUNK_VALUES / cols).clamp(1, rows))
}

/// How a dataset written in blocks stores its values, which arrive as doubles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stored {
    /// 64-bit floats.
    Double,
    /// 32-bit floats (values only drawn).
    Single,
    /// 64-bit integers (node numbers; the doubles hold them exactly below 2^53).
    Index,
}

/// Creates an empty dataset of `rows` × `cols` values (1-D when `cols == 1`) stored as
/// `stored`, chunked and compressed as [`write_matrix`] and [`write_indices`] would write
/// it, for its rows to be written later by [`write_rows`].
pub(super) fn create_values(
    path: &Path,
    g: &Group,
    (name, rows, cols): (&str, usize, usize),
    stored: Stored,
) -> Result<Dataset, OutputError> {
    let mut b = g.new_dataset_builder();
    if let Some(chunk) = chunk_rows(rows, cols) {
        b = compress(match cols {
            1 => b.chunk(chunk),
            _ => b.chunk((chunk, cols)),
        });
    }
    let shape: hdf5::Extents = match cols {
        1 => rows.into(),
        _ => (rows, cols).into(),
    };
    let ctx = || format!("creating {}/{name} [{rows}, {cols}]", g.name());
    match stored {
        Stored::Single => b.empty::<f32>().shape(shape).create(name).ctx(path, ctx),
        Stored::Double => b.empty::<f64>().shape(shape).create(name).ctx(path, ctx),
        Stored::Index => b.empty::<i64>().shape(shape).create(name).ctx(path, ctx),
    }
}

/// Writes `values`, rows of `cols` doubles (stored as `stored`), into rows `first..` of
/// dataset `ds` made by [`create_values`].
pub(super) fn write_rows(
    path: &Path,
    ds: &Dataset,
    (first, cols): (usize, usize),
    values: &[f64],
    stored: Stored,
) -> Result<(), OutputError> {
    let rows = values.len() / cols;
    let ctx = || format!("writing rows {first}..{} of {}", first + rows, ds.name());
    fn write<T: H5Type>(
        ds: &Dataset,
        (first, rows, cols): (usize, usize, usize),
        data: &[T],
    ) -> hdf5::Result<()> {
        if cols == 1 {
            ds.write_slice(ArrayView1::from(data), first..first + rows)
        } else {
            let view = ArrayView2::from_shape((rows, cols), data).map_err(|e| e.to_string())?;
            ds.write_slice(view, (first..first + rows, ..))
        }
    }
    match stored {
        Stored::Double => write(ds, (first, rows, cols), values).ctx(path, ctx),
        Stored::Single => {
            let narrow: Vec<f32> = values.iter().map(|&x| x as f32).collect();
            write(ds, (first, rows, cols), &narrow).ctx(path, ctx)
        }
        Stored::Index => {
            if let Some(&x) = values
                .iter()
                .find(|&&x| !(x >= 0.0 && x < 2f64.powi(53) && x.fract() == 0.0))
            {
                return Err(invalid(path, format!("{}: {x} is not an index", ds.name())));
            }
            let indices: Vec<i64> = values.iter().map(|&x| x as i64).collect();
            write(ds, (first, rows, cols), &indices).ctx(path, ctx)
        }
    }
}

/// As [`write_matrix`] for doubles, stored as 32-bit floats when `single`.
pub(super) fn write_values(
    path: &Path,
    g: &Group,
    (name, rows, cols): (&str, usize, usize),
    data: &[f64],
    single: bool,
) -> Result<Dataset, OutputError> {
    if single {
        let narrow: Vec<f32> = data.iter().map(|&x| x as f32).collect();
        write_matrix(path, g, name, rows, cols, &narrow)
    } else {
        write_matrix(path, g, name, rows, cols, data)
    }
}

/// Shuffle + deflate level 1: cheap, and shuffle (which must precede deflate)
/// makes the slowly varying high bytes of f64/i64 compress well.
fn compress(b: hdf5::dataset::DatasetBuilder) -> hdf5::dataset::DatasetBuilder {
    if hdf5::filters::deflate_available() {
        b.shuffle().deflate(1)
    } else {
        b
    }
}

pub(super) fn write_vec3(
    path: &Path,
    g: &Group,
    name: &str,
    v: &[[f64; 3]],
) -> Result<(), OutputError> {
    write_matrix(path, g, name, v.len(), 3, v.as_flattened()).map(drop)
}

pub(super) fn write_tets(
    path: &Path,
    g: &Group,
    name: &str,
    tets: &[[usize; 4]],
) -> Result<(), OutputError> {
    write_indices(path, g, name, tets)
}

/// Writes rows of N indices as i64 [rows, N] ([rows] when N = 1), compressed when large.
pub(super) fn write_indices<const N: usize>(
    path: &Path,
    g: &Group,
    name: &str,
    rows: &[[usize; N]],
) -> Result<(), OutputError> {
    let mut flat = Vec::with_capacity(rows.len() * N);
    for &i in rows.as_flattened() {
        // Indices were checked against the node count, which is a slice
        // length and so fits in i64 on every supported platform.
        flat.push(i64::try_from(i).map_err(|_| invalid(path, format!("index {i} too large")))?);
    }
    let ctx = || format!("writing {}/{name} [{}, {N}]", g.name(), rows.len());
    let mut b = g.new_dataset_builder();
    if flat.len() >= COMPRESS_MIN_VALUES {
        let chunk_rows = (FRAME_CHUNK_VALUES / N).min(rows.len());
        b = compress(if N == 1 {
            b.chunk(chunk_rows)
        } else {
            b.chunk((chunk_rows, N))
        });
    }
    if N == 1 {
        b.with_data(ArrayView1::from(&flat))
            .create(name)
            .ctx(path, ctx)?;
    } else {
        let view = ArrayView2::from_shape((rows.len(), N), &flat)
            .map_err(|e| invalid(path, format!("{name}: {e}")))?;
        b.with_data(view).create(name).ctx(path, ctx)?;
    }
    Ok(())
}

pub(super) fn check_tets(
    path: &Path,
    what: &str,
    tets: &[[usize; 4]],
    n: usize,
) -> Result<(), OutputError> {
    if let Some((e, t)) = tets
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i >= n))
    {
        return Err(invalid(
            path,
            format!("{what}: tet {e} = {t:?} references a node ≥ node count {n}"),
        ));
    }
    Ok(())
}

/// Opens `g/name`, checking it is 2-D with `cols` columns; returns the dataset and its rows.
pub(super) fn open_2d(
    path: &Path,
    g: &Group,
    name: &str,
    cols: usize,
) -> Result<(Dataset, usize), OutputError> {
    let ds = g
        .dataset(name)
        .ctx(path, || format!("opening {}/{name}", g.name()))?;
    let shape = ds.shape();
    match shape.as_slice() {
        [r, c] if *c == cols => Ok((ds, *r)),
        _ => Err(corrupt(
            path,
            format!(
                "{}/{name} has shape {shape:?}, expected [rows, {cols}]",
                g.name()
            ),
        )),
    }
}

pub(super) fn read_vec3(path: &Path, g: &Group, name: &str) -> Result<Vec<[f64; 3]>, OutputError> {
    let (ds, rows) = open_2d(path, g, name, 3)?;
    let flat = read_range::<f64>(path, &ds, 3, 0..rows)?;
    Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

pub(super) fn read_tets(
    path: &Path,
    g: &Group,
    name: &str,
    n: usize,
) -> Result<Vec<[usize; 4]>, OutputError> {
    let (ds, rows) = open_2d(path, g, name, 4)?;
    read_tet_rows(path, &ds, n, 0..rows)
}

/// Rows `rows` of the tets dataset `ds`, each node index checked to be below `n`.
pub(super) fn read_tet_rows(
    path: &Path,
    ds: &Dataset,
    n: usize,
    rows: Range<usize>,
) -> Result<Vec<[usize; 4]>, OutputError> {
    // Reading as i64 lets HDF5 convert u64/i32/… files too; out-of-range
    // values make the read fail rather than wrap.
    let flat = read_range::<i64>(path, ds, 4, rows.clone())?;
    let mut out = Vec::with_capacity(rows.len());
    for (e, c) in (rows.start..).zip(flat.chunks_exact(4)) {
        let mut t = [0usize; 4];
        for (k, &v) in c.iter().enumerate() {
            t[k] = usize::try_from(v).ok().filter(|&i| i < n).ok_or_else(|| {
                corrupt(
                    path,
                    format!("{}: tet {e} has node index {v} outside 0..{n}", ds.name()),
                )
            })?;
        }
        out.push(t);
    }
    Ok(out)
}

/// Rows `rows` of the 1-D or 2-D dataset `ds` of `cols` columns, row-major, in `T` (HDF5
/// converts the stored number type); `rows` covering the dataset read it in one call.
pub(super) fn read_range<T: H5Type>(
    path: &Path,
    ds: &Dataset,
    cols: usize,
    rows: Range<usize>,
) -> Result<Vec<T>, OutputError> {
    let ctx = || format!("reading rows {}..{} of {}", rows.start, rows.end, ds.name());
    let whole = ds.shape().first() == Some(&rows.end) && rows.start == 0;
    let values = if whole {
        ds.read_raw::<T>().ctx(path, ctx)?
    } else if ds.ndim() == 1 {
        let block = ds.read_slice_1d::<T, _>(rows.clone()).ctx(path, ctx)?;
        block.into_raw_vec_and_offset().0
    } else {
        let block = ds
            .read_slice_2d::<T, _>((rows.clone(), ..))
            .ctx(path, ctx)?;
        block.into_raw_vec_and_offset().0
    };
    if rows.len().checked_mul(cols) != Some(values.len()) {
        return Err(corrupt(path, format!("{}: short read", ds.name())));
    }
    Ok(values)
}

/// Rejects files without the HDF5 signature, which HDF5 searches for at
/// offset 0 and at every power of two from 512 (user blocks).
pub(super) fn check_hdf5_signature(path: &Path) -> Result<(), OutputError> {
    const SIG: [u8; 8] = [0x89, b'H', b'D', b'F', b'\r', b'\n', 0x1a, b'\n'];
    let io = |context: &str| {
        let context = context.to_string();
        move |source| OutputError::Io {
            path: path.to_path_buf(),
            context,
            source,
        }
    };
    let mut f = std::fs::File::open(path).map_err(io("opening"))?;
    let len = f.metadata().map_err(io("reading metadata"))?.len();
    let mut offset = 0u64;
    while offset + 8 <= len {
        use std::io::Seek as _;
        f.seek(std::io::SeekFrom::Start(offset))
            .map_err(io("seeking"))?;
        let mut buf = [0u8; 8];
        f.read_exact(&mut buf).map_err(io("reading"))?;
        if buf == SIG {
            return Ok(());
        }
        offset = if offset == 0 { 512 } else { offset * 2 };
    }
    Err(OutputError::NotHdf5 {
        path: path.to_path_buf(),
    })
}

pub(super) fn check_icefem_layout(path: &Path, file: &File) -> Result<(), OutputError> {
    let not = |reason: &str| OutputError::NotIcefem {
        path: path.to_path_buf(),
        reason: reason.into(),
    };
    if !file.link_exists("mesh") || file.group("mesh").is_err() {
        return Err(not("no /mesh group"));
    }
    let has_version = file
        .attr_names()
        .map(|names| names.iter().any(|n| n == "icefem_version"))
        .unwrap_or(false);
    if !has_version {
        return Err(not("no icefem_version root attribute"));
    }
    if !file.link_exists("frames") || file.group("frames").is_err() {
        return Err(not("no /frames group"));
    }
    Ok(())
}

/// One entry of `/frames`, as found on disk.
pub(super) struct FrameEntry {
    /// Frame index, the number in `/frames/NNNNNN`.
    pub(super) index: usize,
    /// Group name inside `/frames`.
    pub(super) name: String,
    /// Whether the frame carries `complete = 1`.
    pub(super) complete: bool,
}

/// Lists frame groups sorted by index. Members whose names are not decimal
/// indices are ignored (they are not ours to judge).
pub(super) fn list_frames(path: &Path, frames: &Group) -> Result<Vec<FrameEntry>, OutputError> {
    let names = frames
        .member_names()
        .ctx(path, || "listing /frames".into())?;
    let mut out = Vec::new();
    for name in names {
        if name.is_empty() || !name.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let Ok(index) = name.parse::<usize>() else {
            continue;
        };
        // A frame is complete only if the attribute exists and reads as 1;
        // anything else (missing, wrong type, other value) means incomplete.
        let complete = frames
            .group(&name)
            .ok()
            .and_then(|g| g.attr("complete").ok())
            .and_then(|a| a.read_scalar::<u8>().ok())
            == Some(1);
        out.push(FrameEntry {
            index,
            name,
            complete,
        });
    }
    out.sort_by_key(|f| f.index);
    Ok(out)
}

/// Checks that crack surface `c` is whole: a crack id per triangle, its vertices' indices in
/// range.
pub(super) fn check_cracks(path: &Path, c: &CrackSurface) -> Result<(), OutputError> {
    let k = c.vertices.len();
    if c.crack.len() != c.triangles.len() || c.triangles.as_flattened().iter().any(|&i| i >= k) {
        return Err(invalid(
            path,
            format!(
                "crack surface: {} triangles, {} crack ids, indices must be < {k}",
                c.triangles.len(),
                c.crack.len()
            ),
        ));
    }
    Ok(())
}

/// Writes crack surface `c` into group `cracks` of frame group `g` (frame `name`); its
/// vertices in single precision if `single`.
pub(super) fn write_cracks(
    path: &Path,
    g: &Group,
    name: &str,
    c: &CrackSurface,
    single: bool,
) -> Result<(), OutputError> {
    let cg = g
        .create_group("cracks")
        .ctx(path, || format!("creating the cracks of frame {name}"))?;
    let shape = ("vertices", c.vertices.len(), 3);
    write_values(path, &cg, shape, c.vertices.as_flattened(), single)?;
    write_indices(path, &cg, "triangles", &c.triangles)?;
    let ids: Vec<[usize; 1]> = c.crack.iter().map(|&k| [k]).collect();
    write_indices(path, &cg, "crack", &ids)
}

#[cfg(test)]
mod tests {
    use hdf5::File;

    use super::super::test_support::hdf5_guard;
    use super::super::{describe, write_xdmf, OutputError, OutputWriter};

    #[test]
    fn foreign_files_are_rejected() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let text = dir.path().join("notes.h5");
        std::fs::write(&text, "this is not HDF5 at all, just some text\n").unwrap();
        let e = describe(&text).unwrap_err();
        assert!(matches!(e, OutputError::NotHdf5 { .. }), "{e:?}");
        assert!(e.to_string().contains("notes.h5"), "{e}");
        let e = OutputWriter::resume(&text).err().unwrap();
        assert!(matches!(e, OutputError::NotHdf5 { .. }), "{e:?}");

        let empty = dir.path().join("empty.h5");
        std::fs::write(&empty, "").unwrap();
        assert!(matches!(describe(&empty), Err(OutputError::NotHdf5 { .. })));

        let missing = dir.path().join("missing.h5");
        assert!(matches!(describe(&missing), Err(OutputError::Io { .. })));

        let plain = dir.path().join("plain.h5");
        {
            let f = File::create(&plain).unwrap();
            f.new_dataset_builder()
                .with_data(&[1.0f64, 2.0])
                .create("x")
                .unwrap();
        }
        let e = describe(&plain).unwrap_err();
        assert!(matches!(e, OutputError::NotIcefem { .. }), "{e:?}");
        assert!(e.to_string().contains("plain.h5"), "{e}");
        assert!(matches!(
            OutputWriter::resume(&plain),
            Err(OutputError::NotIcefem { .. })
        ));
        assert!(matches!(
            write_xdmf(&plain),
            Err(OutputError::NotIcefem { .. })
        ));

        // /mesh present but no version attribute.
        {
            let f = File::open_rw(&plain).unwrap();
            f.create_group("mesh").unwrap();
        }
        let e = describe(&plain).unwrap_err();
        assert!(e.to_string().contains("icefem_version"), "{e}");
    }
}
