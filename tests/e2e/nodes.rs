//! The fixture nodes of peppy-build, generated with the attribute.

#[peppy::node("peppy-build/tests/fixtures/shapes/peppy.json5")]
pub(crate) mod shapes {}

#[peppy::node("peppy-build/tests/fixtures/conforming_camera/peppy.json5")]
pub(crate) mod zed_2i {}

#[peppy::node("peppy-build/tests/fixtures/repo/nodes/realsense_d405/peppy.json5")]
pub(crate) mod realsense_d405 {}

#[peppy::node("peppy-build/tests/fixtures/video_reconstruction/peppy.json5")]
pub(crate) mod video_reconstruction {}

#[peppy::node("peppy-build/tests/fixtures/robot_arm/peppy.json5")]
pub(crate) mod robot_arm {}

#[peppy::node("peppy-build/tests/fixtures/arm_controller/peppy.json5")]
pub(crate) mod arm_controller {}

#[peppy::node("peppy-build/tests/fixtures/shapes_client/peppy.json5")]
pub(crate) mod shapes_client {}

#[peppy::node("peppy-build/tests/fixtures/arm_commander/peppy.json5")]
pub(crate) mod arm_commander {}

#[peppy::node("peppy-build/tests/fixtures/limb_backbone/peppy.json5")]
pub(crate) mod limb_backbone {}

#[peppy::node("peppy-build/tests/fixtures/limb_panel/peppy.json5")]
pub(crate) mod limb_panel {}
