//! The shipped examples (`examples/`): every document is valid, and the
//! launchers plan (or fail) as their comments say.

use std::collections::BTreeSet;

use peppy_schema::{
    Code, DocumentKind, Identity, Origin, QosProfile, RepoIndex, RepositoryList, RouteFilter,
    SlotBinding, SlotPlan, check_node, load_document,
};
use serde_json::json;

use crate::support::*;

fn set(items: &[&str]) -> BTreeSet<String> {
    items.iter().map(|s| s.to_string()).collect()
}

fn launcher(name: &str) -> std::path::PathBuf {
    examples_dir()
        .join("launchers")
        .join(format!("{name}.json5"))
}

fn depth_camera() -> Identity {
    Identity::new("depth_camera", "v1")
}

#[test]
fn the_examples_directory_is_a_repository() {
    let dir = examples_dir();
    let list =
        RepositoryList::discover(&[], None, &dir.join("nodes/video_reconstruction")).unwrap();
    assert_eq!(list.paths, std::slice::from_ref(&dir));
    assert_eq!(list.files_read, [dir.join("peppy_repositories.json5")]);
    let index = RepoIndex::scan(&list.paths);
    assert!(index.findings().is_empty(), "{}", index.findings());
    // Other examples may be added; these are the ones the tests below use.
    let nodes: Vec<String> = index.node_ids().map(ToString::to_string).collect();
    for id in [
        "arm_controller:v1",
        "camera_mosaic:v1",
        "depth_camera:v1",
        "mujoco_depth_camera_sim:v1",
        "realsense_d405:v1",
        "robot_arm:v1",
        "video_reconstruction:v1",
        "zed_2i:v1",
    ] {
        assert!(
            nodes.iter().any(|n| n == id),
            "`{id}` is not indexed: {nodes:?}"
        );
    }
    assert!(index.interface(&depth_camera()).is_some());
    for name in [
        "multi_camera",
        "multi_camera_sim",
        "robot_arm_loop",
        "three_realsense",
        "wrong_interface",
    ] {
        assert_eq!(index.launcher(name), Some(launcher(name).as_path()));
    }
}

#[test]
fn every_example_document_parses_without_findings() {
    let mut kinds = Vec::new();
    // Fragments are no documents of their own: they are read (all of
    // them, every option's) through their launcher, which is loaded here.
    let fragment = |p: &std::path::Path| {
        std::fs::read_to_string(p).is_ok_and(|t| t.contains("\"launcher_fragment/v1\""))
    };
    for entry in walk(&examples_dir()).into_iter().filter(|p| !fragment(p)) {
        let (doc, warnings) =
            load_document(&entry).unwrap_or_else(|e| panic!("{}:\n{e}", entry.display()));
        // Only the legacy-form example warns, and only about legacy spellings.
        let legacy = entry.ends_with("nodes/gripper/peppy.json5");
        assert!(
            warnings.is_empty()
                || (legacy
                    && warnings
                        .iter()
                        .all(|w| w.code == peppy_schema::Code::LegacySpelling)),
            "{}: {warnings}",
            entry.display()
        );
        kinds.push(doc.kind());
    }
    let count = |k: DocumentKind| kinds.iter().filter(|x| **x == k).count();
    assert!(count(DocumentKind::Node) >= 8, "{kinds:?}");
    assert!(count(DocumentKind::Interface) >= 1, "{kinds:?}");
    assert!(count(DocumentKind::Launcher) >= 5, "{kinds:?}");
    assert_eq!(count(DocumentKind::Repositories), 1);
}

fn walk(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else if p.extension().is_some_and(|x| x == "json5") {
            out.push(p);
        }
    }
    out.sort();
    out
}

#[test]
fn depth_camera_interface_and_its_conforming_nodes() {
    let dir = examples_dir();
    let c = check_node(&dir.join("nodes/realsense_d405"), &options(Vec::new())).unwrap();
    let r = &c.resolved;
    assert_eq!(r.emitted_topics.len(), 1);
    let t = &r.emitted_topics[0];
    assert_eq!(
        (t.decl.name.as_str(), &t.origin, t.decl.qos),
        (
            "video_stream",
            &Origin::Interface(depth_camera()),
            QosProfile::SensorData
        )
    );
    assert_eq!(
        t.decl.format.as_ref().unwrap().canonical(),
        "{header:{stamp:time,frame_id:u32},encoding:string,width:u32,height:u32,frame:[u8]}"
    );
    assert_eq!(r.exposed_services[0].decl.name, "video_stream_info");
    assert!(r.exposed_services[0].decl.request.is_none());
    assert_eq!(
        r.exposed_services[0]
            .decl
            .response
            .as_ref()
            .unwrap()
            .canonical(),
        "{width:u32,height:u32,frames_per_second:u8,encoding:string}"
    );
    assert_eq!(
        r.files,
        [
            dir.join("interfaces/depth_camera.json5"),
            dir.join("nodes/realsense_d405/peppy.json5")
        ]
    );

    // The impostor is named like the interface but provides only its own stream.
    let impostor = check_node(
        &dir.join("nodes/impostor_depth_camera"),
        &options(Vec::new()),
    )
    .unwrap();
    assert!(impostor.resolved.conformed.is_empty());
    assert_eq!(
        impostor.resolved.emitted_topics[0].origin,
        Origin::Node(depth_camera())
    );
}

#[test]
fn video_reconstruction_resolves_its_three_slots() {
    let dir = examples_dir();
    let r = check_node(
        &dir.join("nodes/video_reconstruction"),
        &options(Vec::new()),
    )
    .unwrap()
    .resolved;
    let topics: Vec<(&str, bool, &Origin)> = r
        .consumed_topics
        .iter()
        .map(|t| {
            let slot = t.slot.as_ref().unwrap();
            (
                slot.link_id.as_str(),
                slot.from_any,
                t.origin.as_ref().unwrap(),
            )
        })
        .collect();
    let iface = Origin::Interface(depth_camera());
    assert_eq!(
        topics,
        [
            ("left_cam", false, &iface),
            ("right_cam", false, &iface),
            ("backup_cams", true, &iface)
        ]
    );
    assert_eq!(r.consumed_services[0].slot.link_id, "left_cam");
    assert_eq!(r.consumed_services[0].decl.name, "video_stream_info");
}

#[test]
fn the_robot_arm_pair_links_one_way_and_listens_externally_the_other() {
    let dir = examples_dir();
    let controller = check_node(&dir.join("nodes/arm_controller"), &options(Vec::new()))
        .unwrap()
        .resolved;
    let states = &controller.consumed_topics[0];
    assert_eq!(
        states.origin,
        Some(Origin::Node(Identity::new("robot_arm", "v1")))
    );
    assert_eq!(states.qos, QosProfile::SensorData);
    let arm = check_node(&dir.join("nodes/robot_arm"), &options(Vec::new()))
        .unwrap()
        .resolved;
    let commands = &arm.consumed_topics[0];
    assert!(commands.slot.is_none());
    // The external format matches what the controller emits.
    assert_eq!(
        commands.format.as_ref(),
        controller.emitted_topics[0].decl.format.as_ref()
    );

    let s = stack_ok(&launcher("robot_arm_loop"));
    let c = s.plan.instance("controller").unwrap();
    assert_eq!(
        c.slots[0].binding,
        SlotBinding::Pinned {
            producer: "arm".into()
        }
    );
    assert_eq!(c.parameters, json!({ "step": 0.05, "max_velocity": 1.0 }));
}

fn recon_slots(s: &peppy_schema::StackCheck) -> Vec<(String, SlotBinding, RouteFilter)> {
    s.plan
        .instance("recon_1")
        .unwrap()
        .slots
        .iter()
        .map(|s: &SlotPlan| (s.link_id.clone(), s.binding.clone(), s.filter.clone()))
        .collect()
}

#[test]
fn multi_camera_plans_pinned_cameras_and_a_bound_backup() {
    let s = stack_ok(&launcher("multi_camera"));
    assert!(s.warnings.is_empty(), "{}", s.warnings);
    assert_eq!(
        recon_slots(&s),
        [
            (
                "left_cam".into(),
                SlotBinding::Pinned {
                    producer: "rs_left".into()
                },
                RouteFilter::Pin("rs_left".into())
            ),
            (
                "right_cam".into(),
                SlotBinding::Pinned {
                    producer: "rs_right".into()
                },
                RouteFilter::Pin("rs_right".into())
            ),
            (
                "backup_cams".into(),
                SlotBinding::FromAnyBound {
                    producers: vec!["zed_overhead".into()]
                },
                RouteFilter::OnlyFrom(set(&["zed_overhead"]))
            ),
        ]
    );
    assert_eq!(
        s.plan.instance("rs_left").unwrap().parameters,
        json!({ "width": 160, "height": 120, "frames_per_second": 15 })
    );
    assert_eq!(
        s.plan.instance("zed_overhead").unwrap().parameters,
        json!({ "width": 160, "height": 120, "frames_per_second": 10 })
    );
    assert_eq!(
        s.deployments[2].dir,
        examples_dir().join("nodes/video_reconstruction")
    );
}

#[test]
fn three_realsense_accumulate_in_the_from_any_slot() {
    let s = stack_ok(&launcher("three_realsense"));
    let mosaic = s.plan.instance("mosaic_1").unwrap();
    assert_eq!(mosaic.slots.len(), 1);
    assert_eq!(mosaic.slots[0].link_id, "extras");
    assert_eq!(
        mosaic.slots[0].binding,
        SlotBinding::FromAnyBound {
            producers: vec![
                "rs_front".into(),
                "rs_back_left".into(),
                "rs_back_right".into()
            ]
        }
    );
    assert_eq!(
        mosaic.slots[0].filter,
        RouteFilter::OnlyFrom(set(&["rs_front", "rs_back_left", "rs_back_right"]))
    );
}

#[test]
fn multi_camera_sim_swaps_the_producer_and_keeps_the_consumer() {
    let real = stack_ok(&launcher("multi_camera"));
    let sim = stack_ok(&launcher("multi_camera_sim"));
    assert_eq!(
        sim.plan.instance("rs_left").unwrap().node,
        Identity::new("mujoco_depth_camera_sim", "v1")
    );
    assert_eq!(
        sim.plan.instance("rs_left").unwrap().parameters,
        json!({ "width": 160, "height": 120, "frames_per_second": 20, "fail_after_frames": 0 })
    );
    assert_eq!(recon_slots(&sim), recon_slots(&real));
    assert_eq!(
        sim.plan.instance("recon_1").unwrap().node,
        real.plan.instance("recon_1").unwrap().node
    );
}

#[test]
fn wrong_interface_is_refused_before_anything_starts() {
    let path = launcher("wrong_interface");
    let text = std::fs::read_to_string(&path).unwrap();
    let errors = stack_err(&path);
    assert_eq!(error_codes(&errors), [Code::BindingInterfaceNotConformed]);
    let d = one(&errors, Code::BindingInterfaceNotConformed);
    assert_eq!(key(d), "deployments[2].instances[0].bindings.right_cam");
    assert_eq!(lc(d), pos_nth(&text, r#""impostor""#, 1), "{d}");
    assert_eq!(
        d.message,
        "binding `right_cam` on instance `recon_1`: `impostor` deploys `depth_camera:v1`, which does not conform to interface `depth_camera:v1` required by slot `right_cam`"
    );
    assert_eq!(d.file_path(), Some(path.as_path()));
    assert!(
        d.jump_line(Some(&examples_dir()))
            .starts_with("launchers/wrong_interface.json5:"),
        "{}",
        d.jump_line(None)
    );
}
