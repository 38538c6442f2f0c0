//! `peppylib_camera`'s binary: the node's tasks are in the library
//! (`peppylib_camera::setup`), where its tests reach them too.

use peppygen::{NodeBuilder, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::<Parameters>::new().run(peppylib_camera::setup)
}
