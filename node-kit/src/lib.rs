//! The node kit (docs/architecture.md): plumbing every built-in node shares beside the
//! participant runtime of `protocol` (which holds the params decoder and the checkpoint
//! container). Here: one VTK writer and its ParaView `.pvd` series, used by all four nodes,
//! files written whole or not at all (`whole`), the history tables beside the frames
//! (`table`), and the device choice (`device`, `precision`) of the nodes with GPU kernels.

pub mod device;
pub mod table;
pub mod vtk;
pub mod whole;
