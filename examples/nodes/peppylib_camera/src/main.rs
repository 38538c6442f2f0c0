//! `today_camera`'s binary: the node's tasks are in the library
//! (`today_camera::setup`), where its tests reach them too.

use peppygen::{NodeBuilder, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::<Parameters>::new().run(today_camera::setup)
}
