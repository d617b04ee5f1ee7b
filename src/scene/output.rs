//! `[output]`: the file and what its frames store.

use serde::Deserialize;

use crate::output::FrameOptions;

/// `[output]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// HDF5 file, relative to the working directory. Default: the scene's name with `.h5`.
    pub file: Option<String>,
    /// Store every symmetric tensor (stress, plastic strain) a second time as 3 × 3 matrices,
    /// the layout VTK's XDMF readers (ParaView) read as tensors. Default: true, but false with
    /// a frame every step (`output_every = 1`). Without them files are about a third smaller,
    /// and their XDMF shows the scalars derived from the tensors (von Mises, largest principal
    /// stress, ‖ε_p‖) but not the tensors.
    pub tensor_matrices: Option<bool>,
    /// Store von Mises stress, largest principal stress and ‖ε_p‖ per element beside the
    /// stress they are computed from. Default: true, but false with a frame every step.
    pub derived_scalars: Option<bool>,
    /// Precision of what frames store only to be drawn (positions, stress, the derived
    /// copies, contact forces, crack surfaces): "single" (default: half the bytes, 7
    /// significant digits) or "double". What a resumed run reads is always double.
    pub drawn_precision: Option<DrawnPrecision>,
}

/// `[output] drawn_precision`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DrawnPrecision {
    /// 32-bit floats.
    Single,
    /// 64-bit floats.
    Double,
}

/// The frame options of `[output]` for frames every `output_every` steps: the derived copies
/// are left out by default when a frame is written every step (an animation's frames), where
/// they would be most of the file.
pub(super) fn frame_options(output: &OutputSection, output_every: u64) -> FrameOptions {
    let derived = output_every > 1;
    FrameOptions {
        tensor_matrices: output.tensor_matrices.unwrap_or(derived),
        derived_scalars: output.derived_scalars.unwrap_or(derived),
        drawn_single: output.drawn_precision != Some(DrawnPrecision::Double),
    }
}
