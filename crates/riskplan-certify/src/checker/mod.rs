//! Certification against a whole scene (docs/design.md §5.9–§5.12): one obstacle's
//! constraints over one piece decided by a [`Method`] ([`decide`]), the workspace box
//! (`workspace`), the scene certifier that planners consult as their motion checker
//! ([`SceneCertifier`]) with its fast path ([`SceneIndex`]: proven covers and a grid),
//! the verify path's own frame for the final check ([`FramedContours`]), and the
//! [`SceneKernel`] that holds what all of them cache for one scene.
//!
//! Only a proof counts as safe: an undecided constraint makes the piece unsafe.

mod certifier;
mod compiled_set;
mod cover_index;
mod decide;
mod kernel;
mod verify_path;
mod workspace;

pub use certifier::ObstacleFinding;
pub use certifier::SceneCertifier;
pub use cover_index::{covers_built_total, obstacle_center, piece_bbox, scene_frame, SceneIndex};
pub use decide::{combine, worst};
pub use decide::{
    decide, decide_obstacle, point_obstacle_safe, point_safe, point_safe_with, point_status, Interrupted, Method,
    PointStatus, Status, WitnessReport,
};
pub use kernel::{CompiledSet, SceneKernel};
pub use verify_path::piece_passes_verify_path;
pub use verify_path::{FramedContours, Near, NearBound, NearGrid};
pub use workspace::{check_workspace, inside_by_box, interval_hull, WorkspaceStatus};
