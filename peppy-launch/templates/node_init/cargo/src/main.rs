//! `{{name}}`'s binary: the node's tasks are in the library
//! (`{{crate}}::setup`), where its tests reach them too.

use peppygen::{NodeBuilder, Parameters, Result};

fn main() -> Result<()> {
    NodeBuilder::<Parameters>::new().run({{crate}}::setup)
}
