//! Tet meshes of closed triangle surfaces (`icefem mesh`), made by Gmsh run as a program.
//!
//! The surface is read and checked here ([`TriSurface::read`]: OBJ, STL, PLY or a Gmsh
//! surface), must be closed, and is oriented outward; it is then written as a binary STL
//! beside a `.geo` script in a temporary folder and meshed by `gmsh SCRIPT -3`. By default the
//! surface is remeshed at the asked size (Gmsh's `ClassifySurfaces` and `CreateGeometry`, as
//! in its tutorial t13): the size then holds everywhere, and the boundary follows the
//! surface's facets within that size. `keep_surface` keeps the file's triangles as the mesh's
//! boundary and fills the inside, sizes growing from them up to the asked one.
//!
//! Gmsh exits with status 0 when it makes no tetrahedron (an open or self-intersecting
//! surface: "No elements in volume 1"), so the written file is read back and counted.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use super::gmsh::{self, GmshError};
use super::surface::{InvalidSurface, SurfaceError, TriSurface};

/// How to mesh a surface.
#[derive(Clone, Debug)]
pub struct TetrahedraliseOptions {
    /// Largest element size, in the surface file's units (the mesh is in the same units).
    pub size: f64,
    /// Keep the surface's triangles as the mesh's boundary instead of remeshing it.
    pub keep_surface: bool,
    /// The Gmsh program; `None`: found as [`find_gmsh`] says.
    pub gmsh: Option<PathBuf>,
    /// Replace an existing output file.
    pub force: bool,
}

/// What [`tetrahedralise`] made.
#[derive(Clone, Debug)]
pub struct Tetrahedralised {
    /// Tetrahedra written.
    pub tets: usize,
    /// Nodes written.
    pub nodes: usize,
    /// Triangles of the surface read.
    pub surface_triangles: usize,
    /// Surface triangles turned to face outward before meshing.
    pub reversed: usize,
    /// Volume enclosed by the surface (file units cubed).
    pub surface_volume: f64,
    /// Volume of the tets (file units cubed).
    pub mesh_volume: f64,
    /// The Gmsh program that ran, as it was run.
    pub gmsh: String,
}

/// Why a surface could not be meshed. Every message names the file or the program.
#[derive(Debug, thiserror::Error)]
pub enum TetrahedraliseError {
    /// The surface file could not be read.
    #[error(transparent)]
    Surface(#[from] SurfaceError),
    /// The surface has holes.
    #[error(
        "surface file {path}: the surface is not closed: {edges} edges belong to one triangle \
         (or to more than two), the first from ({:.6}, {:.6}, {:.6}) to ({:.6}, {:.6}, {:.6}); a \
         body needs a closed surface (close its holes in the modeller)",
        from[0], from[1], from[2], to[0], to[1], to[2]
    )]
    Open {
        /// The file.
        path: PathBuf,
        /// Edges not shared by exactly two triangles.
        edges: usize,
        /// One such edge's ends (file units).
        from: [f64; 3],
        /// One such edge's ends (file units).
        to: [f64; 3],
    },
    /// The surface cannot be oriented.
    #[error("surface file {path}: {problem}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong (boxed: it is large, and errors are passed around by value).
        problem: Box<InvalidSurface>,
    },
    /// The size is not a positive number, or would make far too many tets.
    #[error("--size {size}: {reason}")]
    Size {
        /// The size asked.
        size: f64,
        /// What is wrong and what is allowed.
        reason: String,
    },
    /// The output exists and `force` is not set, or it is the input.
    #[error("output {path}: {reason}")]
    Output {
        /// The output path.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// No Gmsh program was found.
    #[error(
        "Gmsh not found (tried {tried}): `make gmsh` installs it into target/gmsh-venv, or give \
         --gmsh PATH (a gmsh program, or the `gmsh` script of a Python environment with the gmsh \
         package)"
    )]
    NoGmsh {
        /// The places looked at.
        tried: String,
    },
    /// Gmsh failed, or made no tetrahedron.
    #[error("{gmsh} on {path}: {reason}{log}")]
    Gmsh {
        /// The program as run.
        gmsh: String,
        /// The surface file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
        /// Gmsh's errors and warnings (empty if none).
        log: String,
    },
    /// A file of the temporary folder could not be written, or the output not copied.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// Why it failed.
        #[source]
        source: std::io::Error,
    },
    /// The mesh Gmsh wrote could not be read back.
    #[error(transparent)]
    Read(#[from] GmshError),
}

/// Most tets `icefem mesh` makes: a run on more would not fit the machines icefem runs on
/// (about 2 kB of memory a tet in a run with fracture).
pub const MAX_TETS: f64 = 2e7;

/// Tets of size h per volume h³: a regular tet of edge h has volume h³/(6√2); Gmsh's meshes
/// come within 10 % of it (546 tets for 573 on a 4 cm ellipsoid at 6 mm).
const TETS_PER_CUBED_SIZE: f64 = 8.5;

/// Meshes the closed surface of file `surface` into `output` (Gmsh 4.1 ASCII, physical
/// volume "body" and physical surface "boundary").
pub fn tetrahedralise(
    surface_path: &Path,
    output: &Path,
    options: &TetrahedraliseOptions,
) -> Result<Tetrahedralised, TetrahedraliseError> {
    let size = options.size;
    if !(size.is_finite() && size > 0.0) {
        return Err(TetrahedraliseError::Size {
            size,
            reason: "must be a finite number > 0, in the surface file's units".into(),
        });
    }
    check_output(surface_path, output, options.force)?;
    let mut surface = TriSurface::read(surface_path, 1.0)?;
    check_closed(surface_path, &surface)?;
    let reversed = surface
        .orient_outward()
        .map_err(|problem| TetrahedraliseError::Invalid {
            path: surface_path.to_path_buf(),
            problem: Box::new(problem),
        })?;
    let surface_volume = surface.enclosed_volume();
    let estimate = TETS_PER_CUBED_SIZE * surface_volume / size.powi(3);
    if estimate > MAX_TETS {
        return Err(TetrahedraliseError::Size {
            size,
            reason: format!(
                "the surface encloses {surface_volume:.3e} (its units cubed): about {estimate:.2e} tets at this size, more than {MAX_TETS:.0e}; give a larger size (in the surface file's units: a surface in millimetres needs a size in millimetres)"
            ),
        });
    }
    let (program, prefix) = find_gmsh(options.gmsh.as_deref())?;
    let shown = std::iter::once(&program)
        .chain(&prefix)
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(" ");
    let folder = tempfile::tempdir().map_err(|source| TetrahedraliseError::Io {
        context: "creating a temporary folder for Gmsh".into(),
        source,
    })?;
    let io = |context: &str| {
        let context = context.to_string();
        move |source| TetrahedraliseError::Io { context, source }
    };
    write_stl(&surface, &folder.path().join("surface.stl"))
        .map_err(io("writing the surface for Gmsh"))?;
    std::fs::write(
        folder.path().join("mesh.geo"),
        geo_script(size, options.keep_surface),
    )
    .map_err(io("writing the Gmsh script"))?;
    let made = folder.path().join("mesh.msh");
    let run = Command::new(&program)
        .args(&prefix)
        .args([
            "mesh.geo", "-3", "-nt", "1", "-format", "msh41", "-o", "mesh.msh",
        ])
        .current_dir(folder.path())
        .output()
        .map_err(io(&format!("running {shown}")))?;
    let log = gmsh_log(&run.stdout, &run.stderr);
    let failed = |reason: String| TetrahedraliseError::Gmsh {
        gmsh: shown.clone(),
        path: surface_path.to_path_buf(),
        reason,
        log: log.clone(),
    };
    if !run.status.success() {
        return Err(failed(format!("it stopped with {}", run.status)));
    }
    let file = match gmsh::read_msh_tagged(&made) {
        Ok(file) => file,
        Err(GmshError::Io { .. }) => return Err(failed("it wrote no mesh".into())),
        Err(e) => return Err(e.into()),
    };
    if file.tets.is_empty() {
        return Err(failed(
            "it made no tetrahedra (a surface that intersects itself, or facets too coarse for the size)".into(),
        ));
    }
    let mesh_volume = file
        .tets
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|i| nalgebra::Vector3::from(file.nodes[i]));
            ((b - a).cross(&(c - a)).dot(&(d - a)) / 6.0).abs()
        })
        .sum();
    std::fs::copy(&made, output).map_err(io(&format!("writing {}", output.display())))?;
    Ok(Tetrahedralised {
        tets: file.tets.len(),
        nodes: file.nodes.len(),
        surface_triangles: surface.triangles.len(),
        reversed,
        surface_volume,
        mesh_volume,
        gmsh: shown,
    })
}

/// The output must not be the input, nor exist unless `force`.
fn check_output(input: &Path, output: &Path, force: bool) -> Result<(), TetrahedraliseError> {
    let refuse = |reason: &str| TetrahedraliseError::Output {
        path: output.to_path_buf(),
        reason: reason.into(),
    };
    if output
        .extension()
        .is_none_or(|e| !e.eq_ignore_ascii_case("msh"))
    {
        return Err(refuse(
            "the mesh is written as a Gmsh file: give a name ending in .msh",
        ));
    }
    let same = std::fs::canonicalize(input)
        .ok()
        .zip(std::fs::canonicalize(output).ok())
        .is_some_and(|(a, b)| a == b);
    if same {
        return Err(refuse("it is the surface file itself"));
    }
    if output.exists() && !force {
        return Err(refuse("it exists; give --force to replace it"));
    }
    Ok(())
}

/// A body's surface must be closed: every edge in exactly two triangles.
fn check_closed(path: &Path, surface: &TriSurface) -> Result<(), TetrahedraliseError> {
    let mut uses: std::collections::HashMap<(usize, usize), u32> = Default::default();
    for t in &surface.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut bad: Vec<(usize, usize)> = uses
        .iter()
        .filter(|(_, &n)| n != 2)
        .map(|(&edge, _)| edge)
        .collect();
    bad.sort_unstable();
    let Some(&(a, b)) = bad.first() else {
        return Ok(());
    };
    Err(TetrahedraliseError::Open {
        path: path.to_path_buf(),
        edges: bad.len(),
        from: surface.vertices[a].into(),
        to: surface.vertices[b].into(),
    })
}

/// The surface as a binary STL (single precision, as the format holds).
fn write_stl(surface: &TriSurface, path: &Path) -> std::io::Result<()> {
    let vertex = |i: usize| {
        let p = surface.vertices[i];
        stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32])
    };
    let triangles: Vec<stl_io::Triangle> = surface
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| surface.vertices[i]);
            let n = (b - a).cross(&(c - a)).normalize();
            stl_io::Triangle {
                normal: stl_io::Normal::new([n.x as f32, n.y as f32, n.z as f32]),
                vertices: t.map(vertex),
            }
        })
        .collect();
    let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
    stl_io::write_stl(&mut file, triangles.iter())?;
    file.flush()
}

/// The Gmsh script: merge the surface, (re)build it as a volume's boundary, mesh at `size`.
fn geo_script(size: f64, keep_surface: bool) -> String {
    // Facets meeting at more than 40° become separate patches, as in Gmsh's tutorial t13.
    let remesh = if keep_surface {
        ""
    } else {
        "ClassifySurfaces{40 * Pi / 180, 1, 1, Pi};\nCreateGeometry;\n"
    };
    format!(
        "// Written by icefem mesh.\n\
         General.NumThreads = 1;\n\
         Mesh.MeshSizeMax = {size:e};\n\
         Mesh.Algorithm3D = 1;\n\
         Merge \"surface.stl\";\n\
         {remesh}\
         Surface Loop(1) = Surface{{:}};\n\
         Volume(1) = {{1}};\n\
         Physical Surface(\"boundary\") = Surface{{:}};\n\
         Physical Volume(\"body\") = {{1}};\n"
    )
}

/// Gmsh's error and warning lines (at most 12), as a suffix of a message.
fn gmsh_log(stdout: &[u8], stderr: &[u8]) -> String {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(stdout),
        String::from_utf8_lossy(stderr)
    );
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("Error") || l.starts_with("Warning"))
        .take(12)
        .collect();
    if lines.is_empty() {
        String::new()
    } else {
        format!("; Gmsh said: {}", lines.join(" | "))
    }
}

/// The Gmsh program and the arguments before the script's: `explicit` if given, else the
/// `GMSH` environment variable, else `gmsh` on `PATH`, else `target/gmsh-venv/bin/gmsh` beside
/// this executable's build folder (what `make gmsh` installs). The `gmsh` script of a Python
/// environment (the gmsh wheel's) starts with `#!/usr/bin/env python`, which finds whatever
/// Python is first on `PATH`: it is run with its environment's own Python instead.
pub fn find_gmsh(explicit: Option<&Path>) -> Result<(PathBuf, Vec<PathBuf>), TetrahedraliseError> {
    let mut candidates: Vec<PathBuf> = Vec::new();
    match explicit {
        Some(path) => candidates.push(path.to_path_buf()),
        None => {
            if let Some(path) = std::env::var_os("GMSH") {
                candidates.push(path.into());
            }
            if let Some(paths) = std::env::var_os("PATH") {
                candidates.extend(std::env::split_paths(&paths).map(|d| d.join("gmsh")));
            }
            if let Ok(exe) = std::env::current_exe() {
                // target/release/icefem → target/gmsh-venv/bin/gmsh
                if let Some(target) = exe.parent().and_then(Path::parent) {
                    candidates.push(target.join("gmsh-venv/bin/gmsh"));
                }
            }
        }
    }
    for candidate in &candidates {
        if !candidate.is_file() {
            continue;
        }
        let head = std::fs::read(candidate)
            .map(|bytes| bytes.into_iter().take(64).collect::<Vec<u8>>())
            .unwrap_or_default();
        let first_line = String::from_utf8_lossy(&head);
        let first_line = first_line.lines().next().unwrap_or("");
        if first_line.starts_with("#!") && first_line.contains("python") {
            let bin = candidate.parent().unwrap_or(Path::new("."));
            if let Some(python) = ["python3", "python"]
                .iter()
                .map(|p| bin.join(p))
                .find(|p| p.is_file())
            {
                return Ok((python, vec![candidate.clone()]));
            }
        }
        return Ok((candidate.clone(), Vec::new()));
    }
    let tried = match explicit {
        Some(path) => path.display().to_string(),
        None => {
            let venv = candidates
                .last()
                .map_or(String::new(), |p| p.display().to_string());
            let env = std::env::var_os("GMSH").map_or("GMSH unset".to_string(), |p| {
                format!("GMSH={}", p.to_string_lossy())
            });
            format!("{env}, gmsh on PATH, {venv}")
        }
    };
    Err(TetrahedraliseError::NoGmsh { tried })
}
