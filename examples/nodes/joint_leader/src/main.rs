//! `joint_leader`'s binary: the node's tasks are in the library
//! (`joint_leader::setup`), where its tests reach them too.

fn main() -> joint_leader::Result<()> {
    joint_leader::NodeBuilder::<joint_leader::Parameters>::new().run(joint_leader::setup)
}
