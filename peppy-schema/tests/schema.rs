//! Integration tests of peppy-schema, one binary with one module per area:
//! JSON5 syntax, node rules, the legacy form, message formats, parameters,
//! launcher rules (both spellings), pairings, repositories, resolution, the
//! binding plan, the shipped examples and a reviewed snapshot of rendered
//! errors.

#[path = "schema/support.rs"]
mod support;

#[path = "schema/binding_plan.rs"]
mod binding_plan;
#[path = "schema/composition.rs"]
mod composition;
#[path = "schema/contracts.rs"]
mod contracts;
#[path = "schema/examples.rs"]
mod examples;
#[path = "schema/formats.rs"]
mod formats;
#[path = "schema/json5_syntax.rs"]
mod json5_syntax;
#[path = "schema/launcher_rules.rs"]
mod launcher_rules;
#[path = "schema/launcher_slash_ids.rs"]
mod launcher_slash_ids;
#[path = "schema/legacy.rs"]
mod legacy;
#[path = "schema/links_slash_ids.rs"]
mod links_slash_ids;
#[path = "schema/node_rules.rs"]
mod node_rules;
#[path = "schema/node_slash_ids.rs"]
mod node_slash_ids;
#[path = "schema/pair_plans.rs"]
mod pair_plans;
#[path = "schema/pairings.rs"]
mod pairings;
#[path = "schema/parameters.rs"]
mod parameters;
#[path = "schema/rendering.rs"]
mod rendering;
#[path = "schema/repositories.rs"]
mod repositories;
#[path = "schema/repository_index.rs"]
mod repository_index;
#[path = "schema/resolution.rs"]
mod resolution;
#[path = "schema/resolution_slash_ids.rs"]
mod resolution_slash_ids;
#[path = "schema/robustness.rs"]
mod robustness;
