//! USD: one text stage, `RUN.usda`, for Blender, Houdini and usdview.
//!
//! The stage: `upAxis = "Z"`, `metersPerUnit = 1`, `framesPerSecond` = `timeCodesPerSecond` =
//! the animation's rate (`--fps`, 30 by default), and a frame at simulated time t at time code
//! (t − t₀) × fps / speed, t₀ the first exported frame's time and speed the simulated seconds
//! per second of animation (`--speed`: 1 plays the run in real time); codes rounded to 1e-6, so
//! that a run written every 1/3 s lands on codes 0, 10, 20, … at 30 fps. A player then holds
//! each sample until the next: the run plays at its own pace whatever its output rate. Three
//! `Mesh` prims, `/World/Ice`, `/World/Cracks` and `/World/Obstacles`, whose
//! `points` (`point3f[]`, m), `faceVertexCounts`, `faceVertexIndices` and `extent` are
//! time-sampled at every frame, since fracture changes the topology (an obstacles attribute
//! that does not change is written once, as its value); `velocities`
//! (`vector3f[]`, m/s) and the primvars `freeze_state`, `plastic_strain`, `von_mises` (Pa) and
//! `temperature` (°C)
//! (`float[]`, `interpolation = "vertex"`, where the run has them) likewise. The layer's
//! `customLayerData` keeps the run's file name, frame indices, frame times (s) and the speed.
//!
//! Floats are f32 written in the shortest form that reads back to the same f32. An attribute's
//! samples must sit together in the text, so the stage is kept in memory as text and written
//! at the end (to a hidden file renamed into place).
//!
//! Written by hand: the `openusd` crate needs rustc 1.96 (we build with 1.95), and USDA is a
//! text format whose few statements here need no library.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::target::Target;
use super::{objects, run_name, write_file, ExportError, ExportFrame, Sink, SurfaceMesh};

/// The prims' names, in the order of the export's objects (ice, cracks, obstacles), and their
/// display colours (linear RGB).
const PRIMS: [(&str, [f32; 3]); 3] = [
    ("Ice", [0.84, 0.92, 1.0]),
    ("Cracks", [0.86, 0.12, 0.1]),
    ("Obstacles", [0.55, 0.58, 0.62]),
];

/// Collects the frames' samples and writes the stage at the end.
pub(super) struct UsdSink {
    file: PathBuf,
    run: String,
    /// (run frame index, time in s, time code) of each exported frame.
    frames: Vec<(usize, f64, f64)>,
    prims: [PrimSamples; 3],
    /// The animation's frames per second.
    fps: f64,
    /// Simulated seconds per second of animation.
    speed: f64,
}

/// The time samples of one `Mesh` prim's attributes, as USDA text: one line per frame each.
#[derive(Default)]
struct PrimSamples {
    extent: String,
    counts: String,
    indices: String,
    points: String,
    velocities: String,
    /// (name, samples) of each primvar, in the order first seen.
    primvars: Vec<(&'static str, String)>,
}

impl UsdSink {
    /// The stage of the run `run` at `target`'s USD file, played at `fps` frames per second,
    /// `speed` simulated seconds per second of animation.
    pub fn new(target: &Target, run: &Path, fps: f64, speed: f64) -> Self {
        UsdSink {
            file: target.usd_file(),
            run: run_name(run),
            frames: Vec::new(),
            prims: Default::default(),
            fps,
            speed,
        }
    }

    /// The time code of simulated time `t` (s): (t − t₀) × fps / speed, rounded to 1e-6 so
    /// that the last bits of the times' sums (30.000000000000004) do not show.
    fn time_code(&self, t: f64) -> f64 {
        let t0 = self.frames.first().map_or(t, |f| f.1);
        ((t - t0) * self.fps / self.speed * 1e6).round() / 1e6
    }
}

impl Sink for UsdSink {
    fn frame(&mut self, frame: &ExportFrame) -> Result<(), ExportError> {
        let code = self.time_code(frame.time);
        if let Some(&(index, _, previous)) = self.frames.last() {
            if code <= previous {
                return Err(ExportError::Invalid {
                    path: self.file.clone(),
                    message: format!(
                        "frames {index} and {} fall on the same time code at --fps {} and \
                         --speed {}: lower the speed or export fewer frames (--frames)",
                        frame.index, self.fps, self.speed
                    ),
                });
            }
        }
        self.frames.push((frame.index, frame.time, code));
        for (prim, (_, mesh)) in self.prims.iter_mut().zip(objects(frame)) {
            prim.push(code, mesh);
        }
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<Vec<PathBuf>, ExportError> {
        let text = self.stage();
        let name = self.file.file_name().unwrap_or_default().to_string_lossy();
        let partial = self
            .file
            .with_file_name(format!(".{name}.{}.partial", std::process::id()));
        write_file(&partial, text.as_bytes())?;
        std::fs::rename(&partial, &self.file).map_err(|source| {
            let _ = std::fs::remove_file(&partial);
            ExportError::Io {
                path: self.file.clone(),
                context: "moving the finished stage into place".into(),
                source,
            }
        })?;
        Ok(vec![self.file])
    }
}

impl UsdSink {
    /// The whole stage.
    fn stage(&self) -> String {
        let mut text = self.layer_header();
        text += "def Xform \"World\"\n{\n";
        // A run without obstacles has no samples for them, and no prim.
        for ((name, colour), prim) in PRIMS.iter().zip(&self.prims) {
            if !prim.points.is_empty() {
                write_mesh_prim(&mut text, name, *colour, prim);
            }
        }
        text += "}\n";
        text
    }

    /// The layer's header: its metadata, the run's frames and the time codes.
    fn layer_header(&self) -> String {
        let list = |values: Vec<String>| values.join(", ");
        let indices = list(self.frames.iter().map(|f| f.0.to_string()).collect());
        let times = list(self.frames.iter().map(|f| f.1.to_string()).collect());
        let (fps, speed) = (self.fps, self.speed);
        format!(
            r#"#usda 1.0
(
    customLayerData = {{
        string icefem_run = "{run}"
        int[] icefem_frames = [{indices}]
        double[] icefem_times = [{times}]
        double icefem_speed = {speed}
    }}
    defaultPrim = "World"
    doc = "icefem export of {run}: the ice's outer surface, its cracks and the rigid obstacles; metres, z up"
    endTimeCode = {end}
    framesPerSecond = {fps}
    metersPerUnit = 1
    startTimeCode = 0
    timeCodesPerSecond = {fps}
    upAxis = "Z"
)

"#,
            run = escape(&self.run),
            end = self.frames.last().map_or(0.0, |f| f.2),
        )
    }
}

/// Appends the `Mesh` prim `name` of display colour `[r, g, b]` with the samples of `prim`.
fn write_mesh_prim(text: &mut String, name: &str, [r, g, b]: [f32; 3], prim: &PrimSamples) {
    // Cracks and open obstacles (a container, a plane) are seen from both sides.
    let double_sided = (name != "Ice") as u8;
    let _ = write!(text, "    def Mesh \"{name}\"\n    {{\n");
    let _ = write!(
        text,
        r#"        uniform bool doubleSided = {double_sided}
        uniform token subdivisionScheme = "none"
        color3f[] primvars:displayColor = [({r}, {g}, {b})] (
            interpolation = "constant"
        )
"#
    );
    // Obstacles that do not move are written once, not once per frame.
    prim.write(text, name == "Obstacles");
    *text += "    }\n";
}

impl PrimSamples {
    /// Adds `mesh` as the samples at time code `k`.
    fn push(&mut self, k: f64, mesh: &SurfaceMesh) {
        let (lo, hi) = extent(&mesh.points);
        sample(&mut self.extent, k, [lo, hi].iter(), push_vec3);
        sample(&mut self.counts, k, mesh.triangles.iter(), |s, _| {
            s.push('3')
        });
        let indices = mesh.triangles.iter().flatten();
        sample(&mut self.indices, k, indices, |s, i| {
            let _ = write!(s, "{i}");
        });
        sample(&mut self.points, k, mesh.points.iter(), push_vec3);
        sample(&mut self.velocities, k, mesh.velocity.iter(), push_vec3);
        for scalar in &mesh.scalars {
            let at = match self.primvars.iter().position(|(n, _)| *n == scalar.name) {
                Some(at) => at,
                None => {
                    self.primvars.push((scalar.name, String::new()));
                    self.primvars.len() - 1
                }
            };
            sample(&mut self.primvars[at].1, k, scalar.values.iter(), |s, v| {
                push_f32(s, *v)
            });
        }
    }

    /// Appends the attributes' declarations with their samples.
    /// Appends the attributes' declarations with their samples; with `constant_if_unchanged`,
    /// an attribute whose samples are all the same is written once, as its value.
    fn write(&self, text: &mut String, constant_if_unchanged: bool) {
        let attributes = [
            ("float3[] extent", &self.extent),
            ("int[] faceVertexCounts", &self.counts),
            ("int[] faceVertexIndices", &self.indices),
            ("point3f[] points", &self.points),
            ("vector3f[] velocities", &self.velocities),
        ];
        for (declaration, samples) in attributes {
            time_samples(text, declaration, samples, constant_if_unchanged);
        }
        for (name, samples) in &self.primvars {
            let declaration = format!("float[] primvars:{name}");
            let _ = write!(
                text,
                "        {declaration} (\n            interpolation = \"vertex\"\n        )\n"
            );
            time_samples(text, &declaration, samples, constant_if_unchanged);
        }
    }
}

/// Appends `declaration.timeSamples = { samples }`, or, with `constant_if_unchanged` and
/// every sample the same, `declaration = value`.
fn time_samples(text: &mut String, declaration: &str, samples: &str, constant_if_unchanged: bool) {
    // A sample line is `            CODE: VALUE,`.
    let mut values = samples
        .lines()
        .map(|line| line.split_once(": ").map(|(_, v)| v.trim_end_matches(',')));
    if constant_if_unchanged {
        if let Some(Some(first)) = values.next() {
            if values.all(|v| v == Some(first)) {
                let _ = writeln!(text, "        {declaration} = {first}");
                return;
            }
        }
    }
    let _ = write!(
        text,
        "        {declaration}.timeSamples = {{\n{samples}        }}\n"
    );
}

/// Appends the sample line `k: [item, item, …],` to `samples`.
fn sample<T>(
    samples: &mut String,
    k: f64,
    items: impl Iterator<Item = T>,
    mut item: impl FnMut(&mut String, T),
) {
    let _ = write!(samples, "            {k}: [");
    for (j, x) in items.enumerate() {
        if j > 0 {
            samples.push_str(", ");
        }
        item(samples, x);
    }
    samples.push_str("],\n");
}

/// The box around `points` (m); zero for none.
fn extent(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    if points.is_empty() {
        return ([0.0; 3], [0.0; 3]);
    }
    points
        .iter()
        .fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), x| {
            (
                std::array::from_fn(|k| lo[k].min(x[k])),
                std::array::from_fn(|k| hi[k].max(x[k])),
            )
        })
}

/// Appends `(x, y, z)` as f32.
fn push_vec3(s: &mut String, v: &[f64; 3]) {
    s.push('(');
    push_f32(s, v[0]);
    s.push_str(", ");
    push_f32(s, v[1]);
    s.push_str(", ");
    push_f32(s, v[2]);
    s.push(')');
}

/// Appends `v` as an f32 in the shortest form that reads back to it (with an exponent outside
/// 1e-4 … 1e7, where the plain form is long).
fn push_f32(s: &mut String, v: f64) {
    let v = v as f32;
    let _ = if v == 0.0 || (1e-4..1e7).contains(&v.abs()) || !v.is_finite() {
        write!(s, "{v}")
    } else {
        write!(s, "{v:e}")
    };
}

/// `s` with the characters a USDA string cannot hold as they are escaped.
fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_read_back_to_the_same_f32() {
        for v in [0.0, 0.1, -2.5e-7, 3.3e9, 1.0 / 3.0, 1e-4, 9.99e6] {
            let mut s = String::new();
            push_f32(&mut s, v);
            assert_eq!(s.parse::<f32>().unwrap(), v as f32, "{s}");
        }
        let mut s = String::new();
        push_f32(&mut s, 2.5e-7);
        assert_eq!(s, "2.5e-7");
    }

    #[test]
    fn unchanged_samples_are_one_value_where_asked() {
        let mut samples = String::new();
        for code in [0.0, 10.0] {
            sample(&mut samples, code, [[0.0, 1.0, 2.0]].iter(), push_vec3);
        }
        let mut text = String::new();
        time_samples(&mut text, "point3f[] points", &samples, true);
        assert_eq!(text, "        point3f[] points = [(0, 1, 2)]\n");
        text.clear();
        time_samples(&mut text, "point3f[] points", &samples, false);
        assert!(text.starts_with("        point3f[] points.timeSamples = {\n"));
        // Samples that differ stay samples.
        sample(&mut samples, 20.0, [[0.0, 1.0, 3.0]].iter(), push_vec3);
        text.clear();
        time_samples(&mut text, "point3f[] points", &samples, true);
        assert_eq!(text.lines().count(), 5);
    }

    #[test]
    fn samples_are_one_line_per_frame() {
        let mut samples = String::new();
        sample(&mut samples, 0.0, [[0.0, 1.0, 2.0]].iter(), push_vec3);
        sample(
            &mut samples,
            12.5,
            std::iter::empty::<&[f64; 3]>(),
            push_vec3,
        );
        assert_eq!(
            samples,
            "            0: [(0, 1, 2)],\n            12.5: [],\n"
        );
    }
}
