//! The writer of the slashed spelling (what `peppy-launch migrate FILE...
//! [--write]` prints or writes): the underscored spelling
//! (`node_v1` and its legacy `schema_version: 1` form, `interface_v1`,
//! `launcher_v1`) rewritten in the slashed one (`node/v1`, `contract/v1`,
//! `launcher/v1`).
//!
//! The rewrite is a list of text edits on the original, placed with the
//! JSON5 reader's spans, so comments, key order and layout survive; only
//! what changes is touched. What the slashed spelling cannot say is not
//! guessed away silently: each such loss is a [`Note`], located in the
//! original where it can be.

use std::collections::BTreeSet;
use std::path::Path;
use std::sync::Arc;

use crate::json::{Member, Node, Value};
use crate::{
    Identity, InterfaceDoc, RepoIndex, RepoOptions, SlotBinding, SourceFile, StackCheck,
    check_launcher, detect_kind, parse_document,
};

/// Something the migration could not carry, or carried only approximately.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Note {
    /// `line:col` in the original file, when the loss has a place.
    pub at: Option<(usize, usize)>,
    /// What was lost and what was done instead.
    pub message: String,
}

/// What migrating one file gives.
#[derive(Debug)]
pub enum Outcome {
    /// Already in the slashed spelling (or not a kind that changed): left
    /// alone.
    AlreadySlashed(&'static str),
    /// The text in the slashed spelling and what it could not carry.
    Migrated {
        /// The new text.
        text: String,
        /// Losses.
        notes: Vec<Note>,
    },
    /// The file cannot be read or is not a peppy document.
    Unreadable(String),
}

/// Text edits on the original: `(start, end, replacement)`.
struct Edits<'t> {
    text: &'t str,
    list: Vec<(usize, usize, String)>,
}

impl<'t> Edits<'t> {
    fn new(text: &'t str) -> Self {
        Edits {
            text,
            list: Vec::new(),
        }
    }

    fn replace(&mut self, start: usize, end: usize, with: impl Into<String>) {
        self.list.push((start, end, with.into()));
    }

    /// Renames a member's key (quotes, if any, are part of the span).
    fn rename(&mut self, m: &Member, to: &str) {
        self.replace(m.key_span.start, m.key_span.end, to);
    }

    /// Replaces a whole `key: value` with `with`.
    fn replace_member(&mut self, m: &Member, with: impl Into<String>) {
        self.replace(m.key_span.start, m.value.span.end, with);
    }

    /// Removes `start..end` with its trailing comma, and the whole line when
    /// nothing else is on it.
    fn remove(&mut self, start: usize, end: usize) {
        let bytes = self.text.as_bytes();
        let mut s = start;
        while s > 0 && matches!(bytes[s - 1], b' ' | b'\t') {
            s -= 1;
        }
        let line_start = s == 0 || bytes[s - 1] == b'\n';
        let mut e = end;
        let skip = |e: &mut usize| {
            while *e < bytes.len() && matches!(bytes[*e], b' ' | b'\t') {
                *e += 1;
            }
        };
        skip(&mut e);
        if e < bytes.len() && bytes[e] == b',' {
            e += 1;
        }
        skip(&mut e);
        let comma = bytes[end..e].contains(&b',');
        if line_start && e < bytes.len() && bytes[e] == b'\n' {
            self.replace(s, e + 1, "");
        } else if comma || line_start {
            self.replace(start, e, "");
        } else if s > 0 && bytes[s - 1] == b',' {
            // The last of an inline list: its separator goes with it.
            self.replace(s - 1, end, "");
        } else {
            self.replace(start, end, "");
        }
    }

    fn remove_member(&mut self, m: &Member) {
        self.remove(m.key_span.start, m.value.span.end);
    }

    fn remove_node(&mut self, n: &Node) {
        self.remove(n.span.start, n.span.end);
    }

    /// The whitespace starting the line `at` is on.
    fn indent_at(&self, at: usize) -> String {
        let line = self.text[..at].rfind('\n').map_or(0, |i| i + 1);
        self.text[line..]
            .chars()
            .take_while(|c| *c == ' ' || *c == '\t')
            .collect()
    }

    fn same_line(&self, a: usize, b: usize) -> bool {
        !self.text[a.min(b)..a.max(b)].contains('\n')
    }

    /// Appends `items` (already written) to the object or array `container`
    /// whose existing items start at `firsts` and end at `lasts`.
    fn append(&mut self, container: &Node, last: Option<(usize, usize)>, items: &[String]) {
        if items.is_empty() {
            return;
        }
        let bytes = self.text.as_bytes();
        match last {
            None => {
                let (open, close) = match container.value {
                    Value::Array(_) => ("[", "]"),
                    _ => ("{", "}"),
                };
                let indent = self.indent_at(container.span.start);
                let body = if items.len() == 1 && items[0].len() < 60 {
                    format!("{open} {} {close}", items[0])
                } else {
                    let inner: String = items.iter().map(|i| format!("\n{indent}  {i},")).collect();
                    format!("{open}{inner}\n{indent}{close}")
                };
                self.replace(container.span.start, container.span.end, body);
            }
            Some((first_start, last_end)) => {
                let mut after = last_end;
                while after < bytes.len() && matches!(bytes[after], b' ' | b'\t') {
                    after += 1;
                }
                let comma = after < bytes.len() && bytes[after] == b',';
                if self.same_line(container.span.start, first_start) {
                    // Inline: `{ a: 1 }` → `{ a: 1, b: 2 }`.
                    let text: String = items.iter().map(|i| format!(", {i}")).collect();
                    if comma {
                        let t: String = items.iter().map(|i| format!(" {i},")).collect();
                        self.replace(after + 1, after + 1, t);
                    } else {
                        self.replace(last_end, last_end, text);
                    }
                } else {
                    let indent = self.indent_at(first_start);
                    let t: String = items.iter().map(|i| format!("\n{indent}{i},")).collect();
                    if comma {
                        self.replace(after + 1, after + 1, t);
                    } else {
                        self.replace(last_end, last_end, format!(",{}", t.trim_end_matches(',')));
                    }
                }
            }
        }
    }

    fn append_members(&mut self, obj: &Node, members: &[String]) {
        let last = match &obj.value {
            Value::Object(ms) => ms
                .first()
                .zip(ms.last())
                .map(|(f, l)| (f.key_span.start, l.value.span.end)),
            _ => return,
        };
        self.append(obj, last, members);
    }

    fn append_items(&mut self, arr: &Node, items: &[String]) {
        let last = match &arr.value {
            Value::Array(xs) => xs
                .first()
                .zip(xs.last())
                .map(|(f, l)| (f.span.start, l.span.end)),
            _ => return,
        };
        self.append(arr, last, items);
    }

    fn apply(mut self) -> String {
        // Back to front, so earlier offsets stay valid; at one offset an
        // insertion goes before a removal starting there.
        self.list.sort_by(|a, b| b.0.cmp(&a.0).then(b.1.cmp(&a.1)));
        let mut out = self.text.to_string();
        for (s, e, with) in self.list {
            out.replace_range(s..e, &with);
        }
        out
    }
}

/// A JSON5 string literal.
fn q(s: &str) -> String {
    serde_json::to_string(s).expect("a string serialises")
}

fn members(n: &Node) -> &[Member] {
    match &n.value {
        Value::Object(ms) => ms,
        _ => &[],
    }
}

fn items(n: Option<&Node>) -> &[Node] {
    match n.map(|n| &n.value) {
        Some(Value::Array(xs)) => xs,
        _ => &[],
    }
}

struct Ctx<'a> {
    file: &'a SourceFile,
    notes: Vec<Note>,
}

impl Ctx<'_> {
    fn note(&mut self, at: Option<usize>, message: impl Into<String>) {
        let at = at.map(|o| {
            let lc = self.file.line_col(o);
            (lc.line, lc.column)
        });
        self.notes.push(Note {
            at,
            message: message.into(),
        });
    }
}

/// Migrates the file at `path`. Contracts a node conforms to and the nodes
/// a launcher deploys are found through the repositories, as `check` finds
/// them.
pub fn migrate_file(path: &Path, options: &RepoOptions) -> Outcome {
    let file = match SourceFile::read(path) {
        Ok((f, _)) => f,
        Err(d) => return Outcome::Unreadable(d.to_string()),
    };
    let root = match crate::json::parse(&file) {
        Ok((root, _)) => root,
        Err(d) => return Outcome::Unreadable(d.to_string()),
    };
    let schema = root.get("peppy_schema").and_then(Node::as_str);
    let legacy = schema.is_none() && root.get("schema_version").is_some();
    match (schema, legacy) {
        (Some("node_v1"), _) | (None, true) => {
            let dir = path.parent().unwrap_or(Path::new("."));
            let index = options.discover(dir).map(|l| RepoIndex::of(&l)).ok();
            let lookup = |id: &Identity| -> Option<Arc<InterfaceDoc>> {
                index.as_ref()?.interface(id).map(|e| e.doc.clone())
            };
            migrate_node(&file, &root, &lookup)
        }
        (Some("interface_v1"), _) => migrate_interface(&file, &root),
        (Some("launcher_v1"), _) => {
            let stack = check_launcher(path, options);
            migrate_launcher(&file, &root, stack.as_ref().map_err(|d| d.error_count()))
        }
        _ => match detect_kind(&root) {
            Some(k) => Outcome::AlreadySlashed(k.as_str()),
            None => Outcome::Unreadable("not a peppy document".into()),
        },
    }
}

/// Finishes a migration: applies the edits and checks the result reads in
/// the slashed spelling; what does not is reported, located in the new
/// text.
fn finish(file: &SourceFile, edits: Edits<'_>, mut ctx: Ctx<'_>) -> Outcome {
    let text = edits.apply();
    let new = SourceFile::new(file.path(), text.clone());
    let sha = crate::sha256_hex(text.as_bytes());
    if let Err(diags) = parse_document(&new, &sha) {
        for d in diags.iter().filter(|d| d.is_error()) {
            ctx.notes.push(Note {
                at: None,
                message: format!("the migrated text does not validate: {d}"),
            });
        }
    }
    Outcome::Migrated {
        text,
        notes: ctx.notes,
    }
}

/// `interface_v1` → `contract/v1`.
pub fn migrate_interface(file: &SourceFile, root: &Node) -> Outcome {
    let mut e = Edits::new(file.text());
    let mut ctx = Ctx {
        file,
        notes: Vec::new(),
    };
    if let Some(m) = root.get_member("peppy_schema") {
        e.replace(m.value.span.start, m.value.span.end, q("contract/v1"));
    }
    if let Some(actions) = root.find_path("interfaces.actions") {
        for a in items(Some(actions)) {
            action_endpoints(&mut e, &mut ctx, a);
        }
    }
    finish(file, e, ctx)
}

/// Action endpoints in the slashed spelling: no `qos_profile` on the goal
/// and result services, no request format on the result service.
fn action_endpoints(e: &mut Edits<'_>, ctx: &mut Ctx<'_>, action: &Node) {
    for svc in ["goal_service", "result_service"] {
        let Some(s) = action.get(svc) else { continue };
        for m in members(s) {
            let dropped = m.key == "qos_profile"
                || (svc == "result_service" && m.key == "request_message_format");
            if dropped {
                ctx.note(
                    Some(m.key_span.start),
                    format!(
                        "`{svc}.{}` has no equivalent in the slashed spelling: removed",
                        m.key
                    ),
                );
                e.remove_member(m);
            }
        }
    }
    if let Some(f) = action.get("feedback_topic")
        && f.get("message_format").is_none()
    {
        ctx.note(
            Some(f.span.start),
            "`feedback_topic.message_format` is required in the slashed spelling: add one",
        );
    }
}

/// `node_v1` (or the legacy `schema_version: 1` form) → `node/v1`.
/// `contract` finds a conformed-to contract's document.
pub fn migrate_node(
    file: &SourceFile,
    root: &Node,
    contract: &dyn Fn(&Identity) -> Option<Arc<InterfaceDoc>>,
) -> Outcome {
    let mut e = Edits::new(file.text());
    let mut ctx = Ctx {
        file,
        notes: Vec::new(),
    };
    match root.get_member("peppy_schema") {
        Some(m) => e.replace(m.value.span.start, m.value.span.end, q("node/v1")),
        None => {
            if let Some(m) = root.get_member("schema_version") {
                e.replace_member(m, format!("peppy_schema: {}", q("node/v1")));
            }
        }
    }
    legacy_forms(&mut e, root);

    // depends_on: `interfaces` → `contracts`, `from_any` → `cardinality`.
    let mut link_ids = BTreeSet::new();
    if let Some(deps) = root.find_path("manifest.depends_on") {
        for m in members(deps) {
            if m.key == "interfaces" {
                e.rename(m, "contracts");
            }
            for d in items(Some(&m.value)) {
                if let Some(l) = d
                    .get("link_id")
                    .or(d.get("local_id"))
                    .and_then(Node::as_str)
                {
                    link_ids.insert(l.to_string());
                }
                if let Some(f) = d.get_member("from_any") {
                    match f.value.value {
                        Value::Bool(true) => {
                            e.replace_member(f, format!("cardinality: {}", q("zero_or_more")))
                        }
                        _ => e.remove_member(f),
                    }
                }
            }
        }
    }

    // conforms_to → manifest.implements plus one entry per member.
    let interfaces = root.get("interfaces");
    let conforms = interfaces.and_then(|i| i.get_member("conforms_to"));
    let mut implements = Vec::new();
    let mut added: [(&str, &str, Vec<String>); 3] = [
        ("topics", "emits", Vec::new()),
        ("services", "exposes", Vec::new()),
        ("actions", "exposes", Vec::new()),
    ];
    if let Some(c) = conforms {
        for entry in items(Some(&c.value)) {
            let (Some(name), Some(tag)) = (
                entry.get("name").and_then(Node::as_str),
                entry.get("tag").and_then(Node::as_str),
            ) else {
                continue;
            };
            let mut link = name.to_string();
            if link_ids.contains(&link) {
                link = format!("{name}_{}", tag.replace(['.', '-'], "_"));
            }
            link_ids.insert(link.clone());
            let sha = entry
                .get("sha256")
                .and_then(Node::as_str)
                .map(|s| format!(", sha256: {}", q(s)))
                .unwrap_or_default();
            implements.push(format!(
                "{{ name: {}, tag: {}, link_id: {}{sha} }}",
                q(name),
                q(tag),
                q(&link)
            ));
            let id = Identity::new(name, tag);
            let Some(doc) = contract(&id) else {
                ctx.note(
                    Some(entry.span.start),
                    format!(
                        "contract `{id}` was not found in the repositories: its members are not listed; add one `{{ link_id: \"{link}\", name }}` per member to `interfaces.topics.emits` / `services.exposes` / `actions.exposes`"
                    ),
                );
                continue;
            };
            let names: [Vec<&str>; 3] = [
                doc.topics.iter().map(|t| t.name.as_str()).collect(),
                doc.services.iter().map(|s| s.name.as_str()).collect(),
                doc.actions.iter().map(|a| a.name.as_str()).collect(),
            ];
            for ((section, list, out), names) in added.iter_mut().zip(names) {
                let natives = interfaces
                    .and_then(|i| i.get(section))
                    .and_then(|s| s.get(list));
                for n in names {
                    if let Some(native) = items(natives).iter().find(|x| {
                        x.get("link_id").is_none()
                            && x.get("name").and_then(Node::as_str) == Some(n)
                    }) {
                        ctx.note(
                            Some(native.span.start),
                            format!(
                                "`{n}` is both declared here and inherited from `{id}`: in `node/v1` they are two entries (the native one and `{{ link_id: \"{link}\", name: \"{n}\" }}`); keep one"
                            ),
                        );
                    }
                    out.push(format!("{{ link_id: {}, name: {} }}", q(&link), q(n)));
                }
            }
        }
    }
    if !implements.is_empty()
        && let Some(manifest) = root.get("manifest")
    {
        let list = if implements.len() == 1 {
            format!("[{}]", implements[0])
        } else {
            let indent = members(manifest)
                .first()
                .map(|m| e.indent_at(m.key_span.start))
                .unwrap_or_default();
            let inner: String = implements
                .iter()
                .map(|i| format!("\n{indent}  {i},"))
                .collect();
            format!("[{inner}\n{indent}]")
        };
        e.append_members(manifest, &[format!("implements: {list}")]);
    }
    if let Some(i) = interfaces {
        let mut new_sections = Vec::new();
        for (section, list, out) in &added {
            if out.is_empty() {
                continue;
            }
            match i.get(section) {
                Some(s) => match s.get(list) {
                    Some(l) => e.append_items(l, out),
                    None => e.append_members(s, &[format!("{list}: {}", inline_list(out))]),
                },
                None => new_sections.push(format!("{section}: {{ {list}: {} }}", inline_list(out))),
            }
        }
        // New sections take `conforms_to`'s place.
        match conforms {
            Some(c) if !new_sections.is_empty() => {
                let indent = e.indent_at(c.key_span.start);
                e.replace_member(c, new_sections.join(&format!(",\n{indent}")));
            }
            Some(c) => e.remove_member(c),
            None => {}
        }

        // External consumed topics and action endpoints.
        for t in items(i.find_path("topics.consumes")) {
            if t.get("link_id").is_none() && t.get("local_node_id").is_none() {
                let name = t.get("name").and_then(Node::as_str).unwrap_or("");
                ctx.note(
                    Some(t.span.start),
                    format!(
                        "external consumed topic `{name}` (any emitter, own `message_format`) has no equivalent in `node/v1`: removed; consume it through a `depends_on` slot instead"
                    ),
                );
                e.remove_node(t);
            }
        }
        for a in items(i.find_path("actions.exposes")) {
            action_endpoints(&mut e, &mut ctx, a);
        }
    }
    finish(file, e, ctx)
}

fn inline_list(items: &[String]) -> String {
    format!("[{}]", items.join(", "))
}

/// The legacy `schema_version: 1` spellings, as the parser's
/// `LegacySpelling` warnings ask.
fn legacy_forms(e: &mut Edits<'_>, root: &Node) {
    let language = root
        .find_path("manifest")
        .and_then(|m| m.get_member("language"));
    if let Some(l) = language {
        e.remove_member(l);
    }
    if let Some(p) = root.get_member("process") {
        e.rename(p, "execution");
        for m in members(&p.value) {
            match m.key.as_str() {
                "add_cmd" => e.rename(m, "build_cmd"),
                "start_cmd" => e.rename(m, "run_cmd"),
                _ => {}
            }
        }
        if let Some(l) = language.and_then(|l| l.value.as_str()) {
            e.append_members(&p.value, &[format!("language: {}", q(l))]);
        }
    }
    if let Some(deps) = root.find_path("manifest.depends_on") {
        for m in members(deps) {
            for d in items(Some(&m.value)) {
                if let Some(k) = d.get_member("local_id") {
                    e.rename(k, "link_id");
                }
            }
        }
    }
    if let Some(i) = root.get("interfaces") {
        for path in ["topics.consumes", "services.consumes", "actions.consumes"] {
            for c in items(i.find_path(path)) {
                if let Some(k) = c.get_member("local_node_id") {
                    e.rename(k, "link_id");
                }
            }
        }
    }
}

/// `launcher_v1` → `launcher/v1`. `stack` is the original checked end to
/// end (or its error count): its plan says which slot each binding filled.
pub fn migrate_launcher(
    file: &SourceFile,
    root: &Node,
    stack: std::result::Result<&StackCheck, usize>,
) -> Outcome {
    let mut e = Edits::new(file.text());
    let mut ctx = Ctx {
        file,
        notes: Vec::new(),
    };
    if let Some(m) = root.get_member("peppy_schema") {
        e.replace(m.value.span.start, m.value.span.end, q("launcher/v1"));
    }
    if let Err(errors) = stack {
        ctx.note(
            root.get_member("peppy_schema").map(|m| m.key_span.start),
            format!(
                "the stack does not check ({errors} error(s); see `peppy-launch check`), so `bindings` were carried as `links` unchanged: a free-form key, or a from_any slot, may need rewriting by hand"
            ),
        );
    }
    for d in items(root.get("deployments")) {
        for inst in items(d.get("instances")) {
            let bindings = inst.get_member("bindings");
            let Ok(stack) = stack else {
                if let Some(b) = bindings {
                    e.rename(b, "links");
                }
                continue;
            };
            let Some(id) = inst.get("instance_id").and_then(Node::as_str) else {
                continue;
            };
            let Some(plan) = stack.plan.instance(id) else {
                continue;
            };
            let mut links = Vec::new();
            for slot in &plan.slots {
                let value = match &slot.binding {
                    SlotBinding::Pinned { producer } => q(producer),
                    SlotBinding::FromAnyBound { producers }
                    | SlotBinding::Set { producers, .. } => list_of(producers),
                    SlotBinding::FromAnyUnbound => {
                        let producers = stack.slot_producers(plan, slot);
                        ctx.note(
                            Some(inst.span.start),
                            format!(
                                "from_any slot `{}` of `{id}` is unbound (it takes any producer; `node/v1`'s `zero_or_more` left empty takes none): wrote the producers it takes in this stack, {}",
                                slot.link_id,
                                list_of(&producers)
                            ),
                        );
                        list_of(&producers)
                    }
                };
                links.push(format!("{}: {value}", slot.link_id));
            }
            for m in bindings.map(|b| members(&b.value)).unwrap_or_default() {
                if !plan.slots.iter().any(|s| s.link_id == m.key) {
                    ctx.note(
                        Some(m.key_span.start),
                        format!(
                            "free-form binding key `{}` has no equivalent: its producer is listed under the from_any slot it filled",
                            m.key
                        ),
                    );
                }
            }
            let text = if links.is_empty() {
                None
            } else {
                Some(format!("links: {{ {} }}", links.join(", ")))
            };
            match (bindings, text) {
                (Some(b), Some(t)) => {
                    let t = if t.len() > 70 || !e.same_line(b.value.span.start, b.value.span.end) {
                        let indent = e.indent_at(b.key_span.start);
                        let inner: String =
                            links.iter().map(|l| format!("\n{indent}  {l},")).collect();
                        format!("links: {{{inner}\n{indent}}}")
                    } else {
                        t
                    };
                    e.replace_member(b, t)
                }
                (Some(b), None) => e.remove_member(b),
                (None, Some(t)) => e.append_members(inst, &[t]),
                (None, None) => {}
            }
        }
    }
    finish(file, e, ctx)
}

fn list_of(producers: &[String]) -> String {
    format!(
        "[{}]",
        producers
            .iter()
            .map(|p| q(p))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn write(dir: &Path, rel: &str, text: &str) -> PathBuf {
        let p = dir.join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, text).unwrap();
        p
    }

    fn options() -> RepoOptions {
        RepoOptions {
            explicit: Vec::new(),
            env: Some(Default::default()),
            last: Vec::new(),
        }
    }

    fn migrated(o: Outcome) -> (String, Vec<Note>) {
        match o {
            Outcome::Migrated { text, notes } => (text, notes),
            other => panic!("not migrated: {other:?}"),
        }
    }

    /// A repository with a camera contract, two cameras and a consumer
    /// with a pinned slot and a from_any slot.
    fn stack(dir: &Path) {
        write(
            dir,
            "peppy_repositories.json5",
            r#"[{ type: "fs", path: "." }]"#,
        );
        write(
            dir,
            "cam_if.json5",
            r#"{ peppy_schema: "interface_v1", manifest: { name: "cam", tag: "v1" },
  interfaces: { topics: [{ name: "frames", message_format: { n: "u32" } }] } }"#,
        );
        write(
            dir,
            "cam/peppy.json5",
            r#"{ peppy_schema: "node_v1", manifest: { name: "camera", tag: "v1" },
  interfaces: { conforms_to: [{ name: "cam", tag: "v1" }] },
  execution: { language: "rust" } }"#,
        );
        write(
            dir,
            "viewer/peppy.json5",
            r#"{ peppy_schema: "node_v1",
  manifest: { name: "viewer", tag: "v1", depends_on: { interfaces: [
    { name: "cam", tag: "v1", link_id: "main" },
    { name: "cam", tag: "v1", link_id: "extra", from_any: true },
  ] } },
  interfaces: { topics: { consumes: [
    { link_id: "main", name: "frames" },
    { link_id: "extra", name: "frames" },
  ] } },
  execution: { language: "rust" } }"#,
        );
    }

    #[test]
    fn a_free_form_key_lands_in_the_from_any_slot_it_filled() {
        let tmp = tempfile::tempdir().unwrap();
        stack(tmp.path());
        let l = write(
            tmp.path(),
            "l.json5",
            r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { local: "cam" }, instances: [{ instance_id: "a" }, { instance_id: "b" }] },
    { source: { local: "viewer" }, instances: [
      { instance_id: "v", bindings: { main: "a", whatever: "b" } },
    ] },
  ],
}"#,
        );
        let (text, notes) = migrated(migrate_file(&l, &options()));
        assert!(
            text.contains(r#"links: { main: "a", extra: ["b"] }"#),
            "{text}"
        );
        assert_eq!(
            notes,
            vec![Note {
                at: Some((6, 50)),
                message: "free-form binding key `whatever` has no equivalent: its producer is listed under the from_any slot it filled".into(),
            }]
        );
    }

    #[test]
    fn an_unbound_from_any_slot_lists_the_producers_it_took() {
        let tmp = tempfile::tempdir().unwrap();
        stack(tmp.path());
        let l = write(
            tmp.path(),
            "l.json5",
            r#"{
  peppy_schema: "launcher_v1",
  deployments: [
    { source: { local: "cam" }, instances: [{ instance_id: "a" }, { instance_id: "b" }, { instance_id: "c" }] },
    { source: { local: "viewer" }, instances: [
      { instance_id: "v", bindings: { main: "a" } },
    ] },
  ],
}"#,
        );
        let (text, notes) = migrated(migrate_file(&l, &options()));
        // `a` is claimed by the pinned slot; `launcher_v1`'s routing gave
        // the from_any slot every other camera.
        assert!(
            text.contains(r#"links: { main: "a", extra: ["b", "c"] }"#),
            "{text}"
        );
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert_eq!(notes[0].at, Some((6, 7)));
        assert!(
            notes[0].message.starts_with("from_any slot `extra` of `v` is unbound (it takes any producer; `node/v1`'s `zero_or_more` left empty takes none): wrote the producers it takes in this stack, [\"b\", \"c\"]"),
            "{}",
            notes[0].message
        );
    }

    #[test]
    fn a_conforming_node_lists_the_contract_members_and_from_any_becomes_a_cardinality() {
        let tmp = tempfile::tempdir().unwrap();
        stack(tmp.path());
        let (text, notes) = migrated(migrate_file(
            &tmp.path().join("cam/peppy.json5"),
            &options(),
        ));
        assert!(notes.is_empty(), "{notes:?}");
        assert!(
            text.contains(r#"implements: [{ name: "cam", tag: "v1", link_id: "cam" }]"#),
            "{text}"
        );
        assert!(
            text.contains(
                r#"interfaces: { topics: { emits: [{ link_id: "cam", name: "frames" }] } }"#
            ),
            "{text}"
        );
        let (text, notes) = migrated(migrate_file(
            &tmp.path().join("viewer/peppy.json5"),
            &options(),
        ));
        assert!(notes.is_empty(), "{notes:?}");
        assert!(text.contains("depends_on: { contracts: ["), "{text}");
        assert!(
            text.contains(r#"link_id: "extra", cardinality: "zero_or_more" }"#),
            "{text}"
        );
    }

    #[test]
    fn a_contract_that_cannot_be_found_is_reported_and_the_rest_migrates() {
        let file = SourceFile::new(
            "peppy.json5",
            r#"{ peppy_schema: "node_v1", manifest: { name: "n", tag: "v1" },
  interfaces: { conforms_to: [{ name: "gone", tag: "v1", sha256: "ab" }] },
  execution: { language: "rust" } }"#,
        );
        let (root, _) = crate::json::parse(&file).unwrap();
        let (text, notes) = migrated(migrate_node(&file, &root, &|_| None));
        assert!(
            text.contains(
                r#"implements: [{ name: "gone", tag: "v1", link_id: "gone", sha256: "ab" }]"#
            ),
            "{text}"
        );
        assert!(!text.contains("conforms_to"), "{text}");
        assert_eq!(notes[0].at, Some((2, 31)));
        assert!(
            notes[0]
                .message
                .starts_with("contract `gone:v1` was not found in the repositories"),
            "{notes:?}"
        );
    }

    #[test]
    fn an_external_topic_is_removed_and_reported() {
        let file = SourceFile::new(
            "peppy.json5",
            "{\n  peppy_schema: \"node_v1\",\n  manifest: { name: \"n\", tag: \"v1\" },\n  interfaces: { topics: { consumes: [\n    // from anyone\n    { name: \"t\", message_format: { x: \"u8\" } },\n  ] } },\n  execution: { language: \"rust\" },\n}\n",
        );
        let (root, _) = crate::json::parse(&file).unwrap();
        let (text, notes) = migrated(migrate_node(&file, &root, &|_| None));
        assert!(!text.contains("message_format"), "{text}");
        assert!(text.contains("// from anyone"), "comments stay: {text}");
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert_eq!(notes[0].at, Some((6, 5)));
        assert!(notes[0].message.starts_with("external consumed topic `t`"));
    }

    #[test]
    fn the_legacy_form_is_spelled_as_its_warnings_ask() {
        let file = SourceFile::new(
            "peppy.json5",
            r#"{
  schema_version: 1,
  manifest: {
    name: "old",
    tag: "v1",
    language: "rust",
    depends_on: { nodes: [{ name: "p", tag: "v1", local_id: "p" }] },
  },
  process: {
    add_cmd: ["cargo", "build"],
    start_cmd: ["./old"],
  },
  interfaces: { topics: { consumes: [{ local_node_id: "p", name: "t" }] } },
}"#,
        );
        let (root, _) = crate::json::parse(&file).unwrap();
        let (text, notes) = migrated(migrate_node(&file, &root, &|_| None));
        assert!(notes.is_empty(), "{notes:?}\n{text}");
        assert!(text.contains(r#"peppy_schema: "node/v1","#), "{text}");
        assert!(
            !text.contains("language: \"rust\",\n    depends_on"),
            "{text}"
        );
        assert!(text.contains("execution: {\n    build_cmd: [\"cargo\", \"build\"],\n    run_cmd: [\"./old\"],\n    language: \"rust\",\n  },"), "{text}");
        assert!(text.contains(r#"link_id: "p" }] }"#), "{text}");
        assert!(text.contains(r#"{ link_id: "p", name: "t" }"#), "{text}");
    }

    #[test]
    fn action_endpoints_lose_what_the_slashed_spelling_does_not_say() {
        let file = SourceFile::new(
            "i.json5",
            r#"{ peppy_schema: "interface_v1", manifest: { name: "i", tag: "v1" },
  interfaces: { actions: [{ name: "go",
    goal_service: { request_message_format: { x: "u8" }, qos_profile: "standard" },
    result_service: { request_message_format: { y: "u8" }, response_message_format: { z: "u8" } },
    feedback_topic: { message_format: { p: "f32" } } }] } }"#,
        );
        let (root, _) = crate::json::parse(&file).unwrap();
        let (text, notes) = migrated(migrate_interface(&file, &root));
        assert!(text.contains(r#"peppy_schema: "contract/v1""#), "{text}");
        assert!(
            text.contains(r#"result_service: { response_message_format: { z: "u8" } }"#),
            "{text}"
        );
        let messages: Vec<_> = notes.iter().map(|n| (n.at, n.message.as_str())).collect();
        assert_eq!(
            messages,
            vec![
                (
                    Some((3, 58)),
                    "`goal_service.qos_profile` has no equivalent in the slashed spelling: removed"
                ),
                (
                    Some((4, 23)),
                    "`result_service.request_message_format` has no equivalent in the slashed spelling: removed"
                ),
            ],
            "{text}"
        );
    }
}
