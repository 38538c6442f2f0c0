//! A stack drawn as a picture: one model, rendered as DOT, SVG or HTML.
//!
//! The model is plain data so that the static `graph` (built from the
//! checked launcher) and the live one (built from what is seen on the wire)
//! draw alike. The SVG is laid out here rather than by Graphviz so that the
//! picture opens on a machine with nothing but a browser.

use std::collections::HashMap;
use std::fmt::Write as _;

/// A picture of a stack: boxes and the arrows between them.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Drawing {
    /// Names the picture (the launcher's file stem).
    pub(crate) title: String,
    /// The boxes, in the order they were found (layout starts from it).
    pub(crate) nodes: Vec<DrawNode>,
    /// The arrows; an edge naming an unknown node id is listed in the HTML
    /// tables but not drawn in the SVG.
    pub(crate) edges: Vec<DrawEdge>,
}

/// One box: usually an instance.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DrawNode {
    /// Unique within the drawing; edges refer to it.
    pub(crate) id: String,
    /// The first line of the box (usually the instance id).
    pub(crate) label: String,
    /// The second line, e.g. `realsense_d405:v1`; empty for none.
    pub(crate) detail: String,
    /// A machine or core node: drawn as a labelled frame around its nodes.
    pub(crate) cluster: Option<String>,
    /// How the box is drawn.
    pub(crate) state: NodeState,
}

/// What is known about a box's process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum NodeState {
    /// In the launcher; nothing is known about it running (the static graph).
    Planned,
    /// Seen running.
    Up,
    /// Expected but not running: greyed, with a dashed border.
    Down,
    /// Not an instance: the `(any)` source of an unbound `from_any` slot.
    Placeholder,
}

impl NodeState {
    /// The word used in the HTML table and as a CSS class.
    pub(crate) fn name(self) -> &'static str {
        match self {
            NodeState::Planned => "planned",
            NodeState::Up => "up",
            NodeState::Down => "down",
            NodeState::Placeholder => "placeholder",
        }
    }
}

/// One arrow from a producer to a consumer.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DrawEdge {
    /// The producing node's id.
    pub(crate) from: String,
    /// The consuming node's id.
    pub(crate) to: String,
    /// Shown on the arrow, e.g. `left_cam` or `left_cam · video_stream 29.9 Hz`.
    pub(crate) label: String,
    /// How the line is stroked.
    pub(crate) style: EdgeStyle,
}

/// How an arrow's line is stroked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EdgeStyle {
    /// A binding, or a flow actually seen.
    Solid,
    /// A possible binding (an unbound `from_any` slot).
    Dashed,
    /// An external topic.
    Dotted,
}

impl EdgeStyle {
    /// The Graphviz `style` attribute, none for solid.
    fn dot(self) -> Option<&'static str> {
        match self {
            EdgeStyle::Solid => None,
            EdgeStyle::Dashed => Some("dashed"),
            EdgeStyle::Dotted => Some("dotted"),
        }
    }

    /// The SVG `stroke-dasharray`, none for solid.
    fn dasharray(self) -> Option<&'static str> {
        match self {
            EdgeStyle::Solid => None,
            EdgeStyle::Dashed => Some("6 4"),
            EdgeStyle::Dotted => Some("2 3"),
        }
    }
}

// ---------------------------------------------------------------- DOT

/// A Graphviz string literal.
fn quote(s: &str) -> String {
    format!(
        "\"{}\"",
        s.replace('\\', "\\\\")
            .replace('"', "\\\"")
            .replace('\n', "\\n")
    )
}

/// The drawing as Graphviz DOT: boxes left to right, clusters as
/// `subgraph "cluster_..."`.
pub(crate) fn dot(drawing: &Drawing) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "digraph {} {{", quote(&drawing.title));
    out.push_str("  rankdir=LR;\n  node [shape=box, fontname=\"monospace\"];\n");
    for node in drawing.nodes.iter().filter(|n| n.cluster.is_none()) {
        dot_node(&mut out, node, "  ");
    }
    for cluster in cluster_names(drawing) {
        let _ = writeln!(
            out,
            "  subgraph {} {{",
            quote(&format!("cluster_{cluster}"))
        );
        let _ = writeln!(out, "    label={};", quote(cluster));
        let members = drawing
            .nodes
            .iter()
            .filter(|n| n.cluster.as_deref() == Some(cluster));
        for node in members {
            dot_node(&mut out, node, "    ");
        }
        out.push_str("  }\n");
    }
    for edge in &drawing.edges {
        dot_edge(&mut out, edge);
    }
    out.push_str("}\n");
    out
}

fn dot_node(out: &mut String, node: &DrawNode, indent: &str) {
    let label = if node.detail.is_empty() {
        node.label.clone()
    } else {
        format!("{}\n{}", node.label, node.detail)
    };
    let extra = match node.state {
        NodeState::Planned => "",
        NodeState::Up => ", style=bold, color=\"darkgreen\"",
        NodeState::Down => ", style=dashed, color=\"gray50\", fontcolor=\"gray50\"",
        NodeState::Placeholder => ", shape=ellipse, style=dashed",
    };
    let _ = writeln!(
        out,
        "{indent}{} [label={}{extra}];",
        quote(&node.id),
        quote(&label)
    );
}

fn dot_edge(out: &mut String, edge: &DrawEdge) {
    let mut attrs = Vec::new();
    if !edge.label.is_empty() {
        attrs.push(format!("label={}", quote(&edge.label)));
    }
    if let Some(style) = edge.style.dot() {
        attrs.push(format!("style={style}"));
    }
    let attrs = if attrs.is_empty() {
        String::new()
    } else {
        format!(" [{}]", attrs.join(", "))
    };
    let _ = writeln!(
        out,
        "  {} -> {}{attrs};",
        quote(&edge.from),
        quote(&edge.to)
    );
}

/// The clusters, in the order their first node appears.
fn cluster_names(drawing: &Drawing) -> Vec<&str> {
    let mut names: Vec<&str> = Vec::new();
    for cluster in drawing.nodes.iter().filter_map(|n| n.cluster.as_deref()) {
        if !names.contains(&cluster) {
            names.push(cluster);
        }
    }
    names
}

// ---------------------------------------------------------------- layout

/// Monospace advance as a fraction of the font size: 7.2 px at 12 px.
const CHAR_EM: f64 = 0.6;
const FONT: f64 = 12.0;
const SMALL_FONT: f64 = 11.0;
const PAD_X: f64 = 10.0;
const PAD_Y: f64 = 6.0;
const LINE_H: f64 = 14.0;
const MIN_NODE_W: f64 = 60.0;
/// Between boxes stacked in one column.
const V_GAP: f64 = 24.0;
/// Between columns when no label needs more.
const MIN_H_GAP: f64 = 64.0;
const LABEL_H: f64 = 16.0;
const LABEL_PAD: f64 = 4.0;
const MARGIN: f64 = 20.0;
const HEADING_H: f64 = 30.0;
const FRAME_PAD: f64 = 12.0;
const FRAME_LABEL_H: f64 = 18.0;
/// Between cluster bands, so frames never touch.
const BAND_GAP: f64 = 24.0;
/// Sideways spacing of parallel edges at their control points; wide enough
/// that their midpoint labels (`LABEL_H`) do not cover each other.
const PARALLEL_STEP: f64 = 28.0;
const LOOP_RISE: f64 = 36.0;
const LOOP_STEP: f64 = 20.0;
/// Barycenter sweeps; crossings rarely improve after a few.
const SWEEPS: usize = 4;

/// Estimated width of `text` at `font` px in a monospace face.
fn text_width(text: &str, font: f64) -> f64 {
    text.chars().count() as f64 * font * CHAR_EM
}

/// An axis-aligned rectangle.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rect {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
}

impl Rect {
    fn cx(&self) -> f64 {
        self.x + self.w / 2.0
    }

    fn cy(&self) -> f64 {
        self.y + self.h / 2.0
    }

    fn right(&self) -> f64 {
        self.x + self.w
    }

    fn bottom(&self) -> f64 {
        self.y + self.h
    }

    fn overlaps(&self, other: &Rect) -> bool {
        self.x < other.right()
            && other.x < self.right()
            && self.y < other.bottom()
            && other.y < self.bottom()
    }
}

/// Where everything goes; indices follow the drawing's nodes and edges.
#[derive(Debug)]
struct Layout {
    boxes: Vec<Rect>,
    /// Each edge's end points as node indices, `None` if one is unknown.
    links: Vec<Option<(usize, usize)>>,
    /// Cluster frames with their names.
    frames: Vec<(String, Rect)>,
    #[cfg_attr(not(test), allow(dead_code))]
    layer: Vec<usize>,
}

/// Lays the drawing out left to right, boxes starting at y = `top`.
fn layout(drawing: &Drawing, top: f64) -> Layout {
    let n = drawing.nodes.len();
    let links = links(drawing);
    let (back, topo) = depth_first(n, &links);
    let layer = longest_path_layers(n, &links, &back, &topo);
    let (band, band_names) = bands(drawing);
    let rows = order_layers(&layer, &band, &links);
    let sizes: Vec<(f64, f64)> = drawing.nodes.iter().map(node_size).collect();
    let xs = column_xs(&rows, &sizes, &layer, &links, drawing);
    let reserve = loop_reserve(n, &links);
    let bands = Bands {
        of: &band,
        names: &band_names,
    };
    let (ys, extents) = place_rows(&rows, &bands, &sizes, &reserve, top);
    let boxes: Vec<Rect> = (0..n)
        .map(|v| Rect {
            x: xs[layer[v]] - sizes[v].0 / 2.0,
            y: ys[v],
            w: sizes[v].0,
            h: sizes[v].1,
        })
        .collect();
    let frames = frames(&extents, &bands, &boxes);
    Layout {
        boxes,
        links,
        frames,
        layer,
    }
}

/// Each edge's end points as node indices (the first node wins a repeated id).
fn links(drawing: &Drawing) -> Vec<Option<(usize, usize)>> {
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (i, node) in drawing.nodes.iter().enumerate() {
        index.entry(node.id.as_str()).or_insert(i);
    }
    drawing
        .edges
        .iter()
        .map(|e| Some((*index.get(e.from.as_str())?, *index.get(e.to.as_str())?)))
        .collect()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mark {
    New,
    Open,
    Done,
}

/// One depth-first search over the nodes in drawing order: which edges are
/// back edges (ignoring them breaks every cycle, self-loops included), and
/// a topological order of what remains (reverse post-order).
fn depth_first(n: usize, links: &[Option<(usize, usize)>]) -> (Vec<bool>, Vec<usize>) {
    let mut out: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (e, &(a, b)) in links
        .iter()
        .enumerate()
        .filter_map(|(e, l)| Some((e, l.as_ref()?)))
    {
        out[a].push((e, b));
    }
    let mut back = vec![false; links.len()];
    let mut mark = vec![Mark::New; n];
    let mut post = Vec::with_capacity(n);
    for root in 0..n {
        if mark[root] != Mark::New {
            continue;
        }
        mark[root] = Mark::Open;
        // Explicit stack: a long chain of nodes must not overflow the thread's.
        let mut stack = vec![(root, 0usize)];
        while let Some(top) = stack.last_mut() {
            let (u, next) = *top;
            let Some(&(e, v)) = out[u].get(next) else {
                mark[u] = Mark::Done;
                post.push(u);
                stack.pop();
                continue;
            };
            top.1 += 1;
            match mark[v] {
                Mark::New => {
                    mark[v] = Mark::Open;
                    stack.push((v, 0));
                }
                Mark::Open => back[e] = true,
                Mark::Done => {}
            }
        }
    }
    post.reverse();
    (back, post)
}

/// Each node's column: the longest path to it from a source, back edges
/// ignored.
fn longest_path_layers(
    n: usize,
    links: &[Option<(usize, usize)>],
    back: &[bool],
    topo: &[usize],
) -> Vec<usize> {
    let mut preds: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (link, _) in links.iter().zip(back).filter(|(_, b)| !**b) {
        if let Some((a, b)) = *link {
            preds[b].push(a);
        }
    }
    let mut layer = vec![0; n];
    for &v in topo {
        layer[v] = preds[v].iter().map(|&u| layer[u] + 1).max().unwrap_or(0);
    }
    layer
}

/// Each node's band: 0 for no cluster, then one per cluster in the order
/// they appear. Bands are stacked top to bottom so that frames never overlap.
fn bands(drawing: &Drawing) -> (Vec<usize>, Vec<Option<String>>) {
    let mut names: Vec<Option<String>> = vec![None];
    let band = drawing
        .nodes
        .iter()
        .map(|node| {
            names
                .iter()
                .position(|n| *n == node.cluster)
                .unwrap_or_else(|| {
                    names.push(node.cluster.clone());
                    names.len() - 1
                })
        })
        .collect();
    (band, names)
}

/// The nodes of each layer, top to bottom: grouped by band, then ordered by
/// a few barycenter sweeps to reduce crossings.
fn order_layers(
    layer: &[usize],
    band: &[usize],
    links: &[Option<(usize, usize)>],
) -> Vec<Vec<usize>> {
    let n = layer.len();
    let depth = layer.iter().max().map_or(0, |m| m + 1);
    let mut rows: Vec<Vec<usize>> = vec![Vec::new(); depth];
    for (v, &l) in layer.iter().enumerate() {
        rows[l].push(v);
    }
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n];
    for &(a, b) in links.iter().flatten().filter(|(a, b)| a != b) {
        neighbours[a].push(b);
        neighbours[b].push(a);
    }
    let mut pos = vec![0.0; n];
    for row in &mut rows {
        let keyed = row.iter().map(|&v| (v, v as f64)).collect();
        sort_row(row, keyed, band, &mut pos);
    }
    for sweep in 0..SWEEPS {
        let downward = sweep % 2 == 0;
        let order: Vec<usize> = if downward {
            (1..depth).collect()
        } else {
            (0..depth.saturating_sub(1)).rev().collect()
        };
        for l in order {
            let side = |w: usize| if downward { layer[w] < l } else { layer[w] > l };
            let keyed = rows[l]
                .iter()
                .map(|&v| (v, barycenter(&neighbours[v], &pos, &side).unwrap_or(pos[v])))
                .collect();
            sort_row(&mut rows[l], keyed, band, &mut pos);
        }
    }
    rows
}

/// The mean position of the neighbours on one side, if there are any.
fn barycenter(neighbours: &[usize], pos: &[f64], side: &dyn Fn(usize) -> bool) -> Option<f64> {
    let on_side: Vec<f64> = neighbours
        .iter()
        .filter(|&&w| side(w))
        .map(|&w| pos[w])
        .collect();
    (!on_side.is_empty()).then(|| on_side.iter().sum::<f64>() / on_side.len() as f64)
}

/// Puts a layer in order of band then key (stable, so ties keep the
/// current order) and records the new positions.
fn sort_row(row: &mut [usize], mut keyed: Vec<(usize, f64)>, band: &[usize], pos: &mut [f64]) {
    keyed.sort_by(|(a, ka), (b, kb)| band[*a].cmp(&band[*b]).then(ka.total_cmp(kb)));
    for (i, (slot, (v, _))) in row.iter_mut().zip(keyed).enumerate() {
        *slot = v;
        pos[v] = i as f64;
    }
}

/// A box's width and height, sized to its text.
fn node_size(node: &DrawNode) -> (f64, f64) {
    let text = text_width(&node.label, FONT).max(text_width(&node.detail, SMALL_FONT));
    let lines = if node.detail.is_empty() { 1.0 } else { 2.0 };
    (
        (text + 2.0 * PAD_X).max(MIN_NODE_W),
        2.0 * PAD_Y + lines * LINE_H,
    )
}

/// How high the `k`-th self-loop on a box rises above it.
fn loop_rise(k: usize) -> f64 {
    LOOP_RISE + LOOP_STEP * k as f64
}

/// The room each box needs above it for its self-loops and their labels.
fn loop_reserve(n: usize, links: &[Option<(usize, usize)>]) -> Vec<f64> {
    let mut loops = vec![0usize; n];
    for &(a, _) in links.iter().flatten().filter(|(a, b)| a == b) {
        loops[a] += 1;
    }
    loops
        .iter()
        .map(|&k| {
            if k == 0 {
                0.0
            } else {
                loop_rise(k - 1) + LABEL_H / 2.0 + 4.0
            }
        })
        .collect()
}

/// The x of each column's centre line: columns as wide as their widest box,
/// gaps as wide as the widest label of the edges starting across them.
fn column_xs(
    rows: &[Vec<usize>],
    sizes: &[(f64, f64)],
    layer: &[usize],
    links: &[Option<(usize, usize)>],
    drawing: &Drawing,
) -> Vec<f64> {
    let widths: Vec<f64> = rows
        .iter()
        .map(|row| row.iter().map(|&v| sizes[v].0).fold(0.0, f64::max))
        .collect();
    let mut gaps = vec![MIN_H_GAP; rows.len()];
    for (link, edge) in links.iter().zip(&drawing.edges) {
        if let Some((a, b)) = *link
            && a != b
        {
            let gap = &mut gaps[layer[a].min(layer[b])];
            *gap = gap.max(label_width(&edge.label) + 2.0 * PAD_X);
        }
    }
    let mut xs = Vec::with_capacity(rows.len());
    let mut left = 0.0;
    for (w, gap) in widths.iter().zip(&gaps) {
        xs.push(left + w / 2.0);
        left += w + gap;
    }
    xs
}

fn label_width(label: &str) -> f64 {
    text_width(label, SMALL_FONT) + 2.0 * LABEL_PAD
}

/// Which band each node is in, and the bands' cluster names.
struct Bands<'a> {
    of: &'a [usize],
    names: &'a [Option<String>],
}

/// A band's index and the vertical extent (top, height) of its boxes.
type Extent = (usize, f64, f64);

/// Each box's y: bands stacked top to bottom, and within a band each
/// column's boxes stacked and centred on the band.
fn place_rows(
    rows: &[Vec<usize>],
    bands: &Bands<'_>,
    sizes: &[(f64, f64)],
    reserve: &[f64],
    top: f64,
) -> (Vec<f64>, Vec<Extent>) {
    let mut ys = vec![0.0; sizes.len()];
    let mut extents = Vec::new();
    let mut cursor = top;
    for (b, name) in bands.names.iter().enumerate() {
        let columns: Vec<Vec<usize>> = rows
            .iter()
            .map(|row| row.iter().copied().filter(|&v| bands.of[v] == b).collect())
            .collect();
        if columns.iter().all(Vec::is_empty) {
            continue;
        }
        let framed = name.is_some();
        let band_top = cursor
            + if framed {
                FRAME_LABEL_H + FRAME_PAD
            } else {
                0.0
            };
        let stack_h = |col: &Vec<usize>| -> f64 {
            let boxes: f64 = col.iter().map(|&v| reserve[v] + sizes[v].1).sum();
            boxes + V_GAP * col.len().saturating_sub(1) as f64
        };
        let band_h = columns.iter().map(stack_h).fold(0.0, f64::max);
        for col in &columns {
            let mut y = band_top + (band_h - stack_h(col)) / 2.0;
            for &v in col {
                ys[v] = y + reserve[v];
                y += reserve[v] + sizes[v].1 + V_GAP;
            }
        }
        extents.push((b, band_top, band_h));
        cursor = band_top + band_h + if framed { FRAME_PAD } else { 0.0 } + BAND_GAP;
    }
    (ys, extents)
}

/// A labelled frame around each cluster band's boxes.
fn frames(extents: &[Extent], bands: &Bands<'_>, boxes: &[Rect]) -> Vec<(String, Rect)> {
    let mut frames = Vec::new();
    for &(b, top, h) in extents {
        let Some(name) = &bands.names[b] else {
            continue;
        };
        let members = boxes.iter().zip(bands.of).filter(|(_, of)| **of == b);
        let (left, right) = members.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, r), (m, _)| {
            (l.min(m.x), r.max(m.right()))
        });
        let rect = Rect {
            x: left - FRAME_PAD,
            y: top - FRAME_LABEL_H - FRAME_PAD,
            w: right - left + 2.0 * FRAME_PAD,
            h: h + FRAME_LABEL_H + 2.0 * FRAME_PAD,
        };
        frames.push((name.clone(), rect));
    }
    frames
}

// ---------------------------------------------------------------- curves

type Point = (f64, f64);

/// A cubic Bézier.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Curve([Point; 4]);

impl Curve {
    /// The point at parameter `t` (0 at the start, 1 at the end).
    fn at(&self, t: f64) -> Point {
        let [p0, p1, p2, p3] = self.0;
        let u = 1.0 - t;
        let (a, b, c, d) = (u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t);
        (
            a * p0.0 + b * p1.0 + c * p2.0 + d * p3.0,
            a * p0.1 + b * p1.1 + c * p2.1 + d * p3.1,
        )
    }

    /// The point halfway along, where a label goes by default.
    #[cfg(test)]
    fn mid(&self) -> Point {
        self.at(0.5)
    }

    fn path(&self) -> String {
        let [p0, p1, p2, p3] = self.0;
        format!(
            "M{} {} C{} {} {} {} {} {}",
            num(p0.0),
            num(p0.1),
            num(p1.0),
            num(p1.1),
            num(p2.0),
            num(p2.1),
            num(p3.0),
            num(p3.1)
        )
    }
}

/// Each edge's curve, `None` for an edge naming an unknown node. Edges
/// between the same two boxes (either way) fan out around the straight
/// route; self-loops on a box nest above it.
fn curves(layout: &Layout) -> Vec<Option<Curve>> {
    let offsets = parallel_offsets(&layout.links);
    let ends = ports(layout, &offsets);
    let mut loops: HashMap<usize, usize> = HashMap::new();
    layout
        .links
        .iter()
        .zip(offsets.iter().zip(&ends))
        .map(|(link, (&offset, end))| {
            let (a, b) = (*link)?;
            if a == b {
                let k = loops.entry(a).or_default();
                *k += 1;
                return Some(loop_curve(&layout.boxes[a], *k - 1));
            }
            let (from, to) = (*end)?;
            let (side, _) = sides(&layout.boxes[a], &layout.boxes[b]);
            let across = matches!(side, Side::Left | Side::Right);
            Some(link_curve(from, to, offset, across))
        })
        .collect()
}

/// How far sideways each edge bends: edges between the same two boxes,
/// either way, spread symmetrically around the straight route.
fn parallel_offsets(links: &[Option<(usize, usize)>]) -> Vec<f64> {
    let pair = |(a, b): (usize, usize)| (a.min(b), a.max(b));
    let mut totals: HashMap<(usize, usize), usize> = HashMap::new();
    for &link in links.iter().flatten().filter(|(a, b)| a != b) {
        *totals.entry(pair(link)).or_default() += 1;
    }
    let mut seen: HashMap<(usize, usize), usize> = HashMap::new();
    links
        .iter()
        .map(|link| match *link {
            Some((a, b)) if a != b => {
                let k = seen.entry(pair((a, b))).or_default();
                let nth = *k as f64;
                *k += 1;
                (nth - (totals[&pair((a, b))] - 1) as f64 / 2.0) * PARALLEL_STEP
            }
            _ => 0.0,
        })
        .collect()
}

/// A side of a box where edges attach.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Side {
    Left,
    Right,
    Top,
    Bottom,
}

/// The sides an edge leaves and enters by: the facing sides of the two
/// columns, or top and bottom within one column.
fn sides(from: &Rect, to: &Rect) -> (Side, Side) {
    if (from.cx() - to.cx()).abs() >= 1.0 {
        if from.cx() < to.cx() {
            (Side::Right, Side::Left)
        } else {
            (Side::Left, Side::Right)
        }
    } else if from.cy() < to.cy() {
        (Side::Bottom, Side::Top)
    } else {
        (Side::Top, Side::Bottom)
    }
}

/// One edge end waiting for its place on a side: sort key (where the other
/// box is, then the bend), then the edge and which end it is.
type PortEnd = ((f64, f64), usize, bool);

/// Where each edge leaves and enters its boxes. Ends sharing a side are
/// spread evenly along it in the order of the boxes at their other ends,
/// so arrowheads do not pile up on one point and lines cross less.
fn ports(layout: &Layout, offsets: &[f64]) -> Vec<Option<(Point, Point)>> {
    let mut by_side: HashMap<(usize, Side), Vec<PortEnd>> = HashMap::new();
    for (e, link) in layout.links.iter().enumerate() {
        let Some((a, b)) = *link else { continue };
        if a == b {
            continue;
        }
        let (ra, rb) = (&layout.boxes[a], &layout.boxes[b]);
        let (sa, sb) = sides(ra, rb);
        let toward = |side: Side, other: &Rect| match side {
            Side::Left | Side::Right => other.cy(),
            Side::Top | Side::Bottom => other.cx(),
        };
        let (ka, kb) = ((toward(sa, rb), offsets[e]), (toward(sb, ra), offsets[e]));
        by_side.entry((a, sa)).or_default().push((ka, e, true));
        by_side.entry((b, sb)).or_default().push((kb, e, false));
    }
    let mut ends: Vec<(Point, Point)> = vec![((0.0, 0.0), (0.0, 0.0)); layout.links.len()];
    // Each side's result depends only on its own ends, so the map's order
    // does not reach the output.
    for ((v, side), mut group) in by_side {
        group.sort_by(|(ka, ea, _), (kb, eb, _)| {
            ka.0.total_cmp(&kb.0)
                .then(ka.1.total_cmp(&kb.1))
                .then(ea.cmp(eb))
        });
        let m = group.len();
        for (k, (_, e, is_from)) in group.into_iter().enumerate() {
            let point = port(&layout.boxes[v], side, k, m);
            if is_from {
                ends[e].0 = point;
            } else {
                ends[e].1 = point;
            }
        }
    }
    layout
        .links
        .iter()
        .zip(ends)
        .map(|(link, end)| link.filter(|(a, b)| a != b).map(|_| end))
        .collect()
}

/// The `k`-th of `m` evenly spaced points along one side of a box.
fn port(r: &Rect, side: Side, k: usize, m: usize) -> Point {
    let f = (k + 1) as f64 / (m + 1) as f64;
    match side {
        Side::Left => (r.x, r.y + r.h * f),
        Side::Right => (r.right(), r.y + r.h * f),
        Side::Top => (r.x + r.w * f, r.y),
        Side::Bottom => (r.x + r.w * f, r.bottom()),
    }
}

/// From one port to another, leaving and arriving horizontally when
/// `across` columns (vertically within one), bent `offset` px sideways.
fn link_curve(p0: Point, p3: Point, offset: f64, across: bool) -> Curve {
    if across {
        let dx = (p3.0 - p0.0) / 2.0;
        Curve([
            p0,
            (p0.0 + dx, p0.1 + offset),
            (p3.0 - dx, p3.1 + offset),
            p3,
        ])
    } else {
        let dy = (p3.1 - p0.1) / 2.0;
        Curve([
            p0,
            (p0.0 + offset, p0.1 + dy),
            (p3.0 + offset, p3.1 - dy),
            p3,
        ])
    }
}

/// Where along its curve each label goes: halfway if that is clear of the
/// boxes and of the labels placed before it, else the nearest clear point
/// from a few tried; halfway when none is.
fn label_spots(drawing: &Drawing, layout: &Layout, curves: &[Option<Curve>]) -> Vec<Option<Point>> {
    const TRIES: [f64; 7] = [0.5, 0.4, 0.6, 0.3, 0.7, 0.25, 0.75];
    let mut placed: Vec<Rect> = Vec::new();
    curves
        .iter()
        .zip(&drawing.edges)
        .map(|(curve, edge)| {
            let curve = (*curve)?;
            let clear = |at: Point| {
                let r = label_rect(&edge.label, at);
                !placed.iter().chain(&layout.boxes).any(|o| r.overlaps(o))
            };
            let at = TRIES
                .iter()
                .map(|&t| curve.at(t))
                .find(|&at| clear(at))
                .unwrap_or_else(|| curve.at(0.5));
            if !edge.label.is_empty() {
                placed.push(label_rect(&edge.label, at));
            }
            Some(at)
        })
        .collect()
}

/// The `k`-th loop over the top of a box, peaking `loop_rise(k)` above it.
fn loop_curve(r: &Rect, k: usize) -> Curve {
    // A cubic with both control points at height c peaks at 3c/4.
    let c = loop_rise(k) * 4.0 / 3.0;
    // Outer loops start wider apart so nested loops do not touch.
    let foot = 10.0 + 6.0 * k as f64;
    let spread = 30.0 + 12.0 * k as f64;
    let (cx, top) = (r.cx(), r.y);
    Curve([
        (cx + foot, top),
        (cx + foot + spread, top - c),
        (cx - foot - spread, top - c),
        (cx - foot, top),
    ])
}

// ---------------------------------------------------------------- SVG

/// A coordinate, always with one decimal so the output is byte-stable.
fn num(v: f64) -> String {
    format!("{v:.1}")
}

/// Escapes text and attribute values for XML and HTML.
fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// The smallest rectangle around everything drawn.
#[derive(Debug, Clone, Copy)]
struct Bounds {
    min: Point,
    max: Point,
}

impl Bounds {
    fn new() -> Self {
        Bounds {
            min: (f64::INFINITY, f64::INFINITY),
            max: (f64::NEG_INFINITY, f64::NEG_INFINITY),
        }
    }

    fn point(&mut self, p: Point) {
        self.min = (self.min.0.min(p.0), self.min.1.min(p.1));
        self.max = (self.max.0.max(p.0), self.max.1.max(p.1));
    }

    fn rect(&mut self, r: &Rect) {
        self.point((r.x, r.y));
        self.point((r.right(), r.bottom()));
    }

    /// The view box, with a margin; a blank square when nothing is drawn.
    fn view(&self) -> Rect {
        if self.min.0 > self.max.0 {
            return Rect {
                x: -MARGIN,
                y: -MARGIN,
                w: 2.0 * MARGIN,
                h: 2.0 * MARGIN,
            };
        }
        Rect {
            x: self.min.0 - MARGIN,
            y: self.min.1 - MARGIN,
            w: self.max.0 - self.min.0 + 2.0 * MARGIN,
            h: self.max.1 - self.min.1 + 2.0 * MARGIN,
        }
    }
}

/// The white box behind an edge label, centred on the curve's midpoint.
fn label_rect(label: &str, at: Point) -> Rect {
    let w = label_width(label);
    Rect {
        x: at.0 - w / 2.0,
        y: at.1 - LABEL_H / 2.0,
        w,
        h: LABEL_H,
    }
}

/// The drawing as a self-contained SVG document, laid out here (no
/// Graphviz): columns left to right, the title on top.
pub(crate) fn svg(drawing: &Drawing) -> String {
    render_svg(drawing, true)
}

/// `heading`: whether to write the title above the picture (the HTML page
/// has its own).
fn render_svg(drawing: &Drawing, heading: bool) -> String {
    let top = if heading { HEADING_H } else { 0.0 };
    let layout = layout(drawing, top);
    let curves = curves(&layout);
    let spots = label_spots(drawing, &layout, &curves);
    let mut bounds = Bounds::new();
    if heading {
        bounds.rect(&Rect {
            x: 0.0,
            y: 0.0,
            w: text_width(&drawing.title, 14.0),
            h: HEADING_H,
        });
    }
    layout.boxes.iter().for_each(|r| bounds.rect(r));
    layout.frames.iter().for_each(|(_, r)| bounds.rect(r));
    for curve in curves.iter().flatten() {
        curve.0.iter().for_each(|&p| bounds.point(p));
    }
    for (spot, edge) in spots.iter().zip(&drawing.edges) {
        if let Some(at) = spot {
            bounds.rect(&label_rect(&edge.label, *at));
        }
    }
    let view = bounds.view();
    let mut out = String::new();
    svg_open(&mut out, drawing, &view);
    if heading {
        let _ = writeln!(
            out,
            "<text x=\"0\" y=\"18\" font-size=\"14\" font-weight=\"bold\">{}</text>",
            escape(&drawing.title)
        );
    }
    svg_frames(&mut out, &layout);
    svg_edges(&mut out, drawing, &curves);
    svg_nodes(&mut out, drawing, &layout);
    svg_labels(&mut out, drawing, &spots);
    out.push_str("</svg>\n");
    out
}

fn svg_open(out: &mut String, drawing: &Drawing, view: &Rect) {
    let _ = writeln!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" \
         viewBox=\"{} {} {w} {h}\" font-family=\"monospace\" font-size=\"{FONT}\" \
         role=\"img\" aria-label=\"{t}\">",
        num(view.x),
        num(view.y),
        w = num(view.w),
        h = num(view.h),
        t = escape(&drawing.title),
    );
    let _ = writeln!(out, "<title>{}</title>", escape(&drawing.title));
    out.push_str(
        "<defs><marker id=\"peppy-arrow\" viewBox=\"0 0 10 10\" refX=\"9\" refY=\"5\" \
         markerWidth=\"9\" markerHeight=\"9\" markerUnits=\"userSpaceOnUse\" orient=\"auto\">\
         <path d=\"M0 0 L10 5 L0 10 z\" fill=\"#444\"/></marker></defs>\n",
    );
    // A background of its own, so the picture reads on dark viewers too.
    let _ = writeln!(
        out,
        "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"white\"/>",
        num(view.x),
        num(view.y),
        num(view.w),
        num(view.h)
    );
}

fn svg_frames(out: &mut String, layout: &Layout) {
    out.push_str("<g class=\"clusters\">\n");
    for (name, r) in &layout.frames {
        let _ = writeln!(
            out,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" rx=\"8\" fill=\"#f7f9fc\" \
             stroke=\"#8fa3bf\"/><text x=\"{}\" y=\"{}\" font-size=\"{SMALL_FONT}\" \
             fill=\"#41587a\">{}</text>",
            num(r.x),
            num(r.y),
            num(r.w),
            num(r.h),
            num(r.x + 8.0),
            num(r.y + FRAME_LABEL_H - 3.0),
            escape(name)
        );
    }
    out.push_str("</g>\n");
}

fn svg_edges(out: &mut String, drawing: &Drawing, curves: &[Option<Curve>]) {
    out.push_str("<g class=\"edges\" fill=\"none\" stroke=\"#444\" stroke-width=\"1.4\">\n");
    for (curve, edge) in curves.iter().zip(&drawing.edges) {
        let Some(curve) = curve else { continue };
        let dash = edge
            .style
            .dasharray()
            .map(|d| format!(" stroke-dasharray=\"{d}\""))
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "<path d=\"{}\"{dash} marker-end=\"url(#peppy-arrow)\"><title>{} \u{2192} {}: {}</title></path>",
            curve.path(),
            escape(&edge.from),
            escape(&edge.to),
            escape(&edge.label)
        );
    }
    out.push_str("</g>\n");
}

/// Fill, stroke, dash and text colour of a box.
fn node_colours(
    state: NodeState,
) -> (
    &'static str,
    &'static str,
    Option<&'static str>,
    &'static str,
) {
    match state {
        NodeState::Planned => ("#ffffff", "#333333", None, "#111111"),
        NodeState::Up => ("#e8f5e9", "#2e7d32", None, "#111111"),
        NodeState::Down => ("#eeeeee", "#999999", Some("5 3"), "#888888"),
        NodeState::Placeholder => ("#ffffff", "#666666", Some("4 3"), "#444444"),
    }
}

fn svg_nodes(out: &mut String, drawing: &Drawing, layout: &Layout) {
    out.push_str("<g class=\"nodes\">\n");
    for (node, r) in drawing.nodes.iter().zip(&layout.boxes) {
        let (fill, stroke, dash, ink) = node_colours(node.state);
        let dash = dash
            .map(|d| format!(" stroke-dasharray=\"{d}\""))
            .unwrap_or_default();
        // The placeholder is a pill, echoing Graphviz's ellipse.
        let rx = if node.state == NodeState::Placeholder {
            r.h / 2.0
        } else {
            6.0
        };
        let _ = writeln!(
            out,
            "<g class=\"node {}\"><title>{}</title>\
             <rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" rx=\"{}\" fill=\"{fill}\" \
             stroke=\"{stroke}\" stroke-width=\"1.2\"{dash}/>",
            node.state.name(),
            escape(&tooltip(node)),
            num(r.x),
            num(r.y),
            num(r.w),
            num(r.h),
            num(rx)
        );
        node_text(out, &node.label, r, 0, FONT, ink, true);
        if !node.detail.is_empty() {
            node_text(out, &node.detail, r, 1, SMALL_FONT, ink, false);
        }
        out.push_str("</g>\n");
    }
    out.push_str("</g>\n");
}

fn tooltip(node: &DrawNode) -> String {
    let mut tip = node.id.clone();
    if !node.detail.is_empty() {
        let _ = write!(tip, " ({})", node.detail);
    }
    let _ = write!(tip, ": {}", node.state.name());
    tip
}

/// One line of a box's text, centred; the baseline sits about 0.35 em
/// below the line's middle since `dominant-baseline` is not honoured
/// everywhere.
fn node_text(
    out: &mut String,
    text: &str,
    r: &Rect,
    line: usize,
    font: f64,
    ink: &str,
    bold: bool,
) {
    let middle = r.y + PAD_Y + LINE_H * (line as f64 + 0.5);
    let weight = if bold { " font-weight=\"bold\"" } else { "" };
    let _ = write!(
        out,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"{font}\" fill=\"{ink}\"{weight}>{}</text>",
        num(r.cx()),
        num(middle + font * 0.35),
        escape(text)
    );
}

fn svg_labels(out: &mut String, drawing: &Drawing, spots: &[Option<Point>]) {
    out.push_str("<g class=\"labels\">\n");
    for (spot, edge) in spots.iter().zip(&drawing.edges) {
        let Some(at) = *spot else { continue };
        if edge.label.is_empty() {
            continue;
        }
        let r = label_rect(&edge.label, at);
        let _ = writeln!(
            out,
            "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" rx=\"3\" fill=\"white\" \
             fill-opacity=\"0.9\"/><text x=\"{}\" y=\"{}\" text-anchor=\"middle\" \
             font-size=\"{SMALL_FONT}\" fill=\"#222222\">{}</text>",
            num(r.x),
            num(r.y),
            num(r.w),
            num(r.h),
            num(at.0),
            num(at.1 + SMALL_FONT * 0.35),
            escape(&edge.label)
        );
    }
    out.push_str("</g>\n");
}

// ---------------------------------------------------------------- HTML

const STYLE: &str = "body { font-family: system-ui, sans-serif; margin: 1.5rem; color: #222; }
figure { margin: 0 0 1.5rem; overflow-x: auto; }
svg { max-width: 100%; height: auto; }
table { border-collapse: collapse; margin-bottom: 1.5rem; }
th, td { border: 1px solid #bbb; padding: 0.2rem 0.6rem; text-align: left; font-family: monospace; }
th { background: #f0f0f0; }
@media print { figure { overflow: visible; } h2 { break-after: avoid; } }
";

/// The drawing as a standalone HTML5 page (no scripts, no external
/// resources): the title, the SVG, and tables of the edges and nodes so the
/// page still says everything when printed.
pub(crate) fn html(drawing: &Drawing) -> String {
    let title = escape(&drawing.title);
    let mut out = String::new();
    let _ = write!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n\
         <title>{title}</title>\n<style>\n{STYLE}</style>\n</head>\n<body>\n<h1>{title}</h1>\n<figure>\n"
    );
    out.push_str(&render_svg(drawing, false));
    out.push_str("</figure>\n");
    edge_table(&mut out, drawing);
    node_table(&mut out, drawing);
    out.push_str("</body>\n</html>\n");
    out
}

fn table_row(out: &mut String, cell: &str, cells: &[&str]) {
    out.push_str("<tr>");
    for c in cells {
        let _ = write!(out, "<{cell}>{}</{cell}>", escape(c));
    }
    out.push_str("</tr>\n");
}

fn edge_table(out: &mut String, drawing: &Drawing) {
    let _ = writeln!(out, "<h2>Edges ({})</h2>", drawing.edges.len());
    out.push_str("<table>\n<thead>\n");
    table_row(out, "th", &["from", "to", "label"]);
    out.push_str("</thead>\n<tbody>\n");
    for e in &drawing.edges {
        table_row(out, "td", &[&e.from, &e.to, &e.label]);
    }
    out.push_str("</tbody>\n</table>\n");
}

fn node_table(out: &mut String, drawing: &Drawing) {
    // A cluster column only when there are clusters, to keep the static
    // graph's table narrow.
    let clustered = drawing.nodes.iter().any(|n| n.cluster.is_some());
    let _ = writeln!(out, "<h2>Nodes ({})</h2>", drawing.nodes.len());
    out.push_str("<table>\n<thead>\n");
    let mut head = vec!["id", "detail", "state"];
    if clustered {
        head.push("cluster");
    }
    table_row(out, "th", &head);
    out.push_str("</thead>\n<tbody>\n");
    for n in &drawing.nodes {
        let mut cells = vec![n.id.as_str(), n.detail.as_str(), n.state.name()];
        if clustered {
            cells.push(n.cluster.as_deref().unwrap_or(""));
        }
        table_row(out, "td", &cells);
    }
    out.push_str("</tbody>\n</table>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(id: &str, detail: &str, cluster: Option<&str>, state: NodeState) -> DrawNode {
        DrawNode {
            id: id.into(),
            label: id.into(),
            detail: detail.into(),
            cluster: cluster.map(Into::into),
            state,
        }
    }

    fn edge(from: &str, to: &str, label: &str, style: EdgeStyle) -> DrawEdge {
        DrawEdge {
            from: from.into(),
            to: to.into(),
            label: label.into(),
            style,
        }
    }

    /// The arm loop, plus what the live graph adds: clusters, states,
    /// parallel slots between one pair, a self-loop and a placeholder.
    fn sample() -> Drawing {
        Drawing {
            title: "robot_arm_loop".into(),
            nodes: vec![
                node("arm", "robot_arm:v1", Some("core-a"), NodeState::Up),
                node(
                    "controller",
                    "arm_controller:v1",
                    Some("core-a"),
                    NodeState::Up,
                ),
                node("cam", "realsense_d405:v1", Some("core-b"), NodeState::Down),
                node("recon", "video_reconstruction:v1", None, NodeState::Planned),
                node("recon.backup_cams.any", "", None, NodeState::Placeholder),
            ],
            edges: vec![
                edge("arm", "controller", "robot_arm", EdgeStyle::Solid),
                edge(
                    "controller",
                    "arm",
                    "joint_commands (external)",
                    EdgeStyle::Dotted,
                ),
                edge(
                    "cam",
                    "recon",
                    "left_cam · video_stream 29.9 Hz",
                    EdgeStyle::Solid,
                ),
                edge("cam", "recon", "right_cam", EdgeStyle::Solid),
                edge("recon", "recon", "feedback", EdgeStyle::Solid),
                edge("recon", "recon", "feedback_2", EdgeStyle::Solid),
                edge(
                    "recon.backup_cams.any",
                    "recon",
                    "backup_cams (any)",
                    EdgeStyle::Dashed,
                ),
            ],
        }
    }

    /// A minimal well-formedness check: tags balance, attribute values are
    /// quoted, and every `&` starts an entity.
    fn assert_well_formed(xml: &str) {
        let mut open: Vec<String> = Vec::new();
        let mut rest = xml;
        while let Some(start) = rest.find('<') {
            assert_text_ok(&rest[..start]);
            let end = rest[start..].find('>').expect("unclosed tag") + start;
            let tag = &rest[start + 1..end];
            rest = &rest[end + 1..];
            if tag.starts_with('!') || tag.starts_with('?') {
                continue;
            }
            assert_eq!(
                tag.matches('"').count() % 2,
                0,
                "unbalanced quotes in <{tag}>"
            );
            assert!(!tag.contains('<'), "`<` inside <{tag}>");
            assert_text_ok(tag);
            let name: String = tag
                .trim_start_matches('/')
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '-')
                .collect();
            assert!(!name.is_empty(), "nameless tag <{tag}>");
            if let Some(closing) = tag.strip_prefix('/') {
                assert_eq!(
                    open.pop().as_deref(),
                    Some(closing.trim()),
                    "mismatched </{closing}>"
                );
            } else if !tag.ends_with('/') {
                open.push(name);
            }
        }
        assert_text_ok(rest);
        assert!(open.is_empty(), "unclosed: {open:?}");
    }

    fn assert_text_ok(text: &str) {
        assert!(
            !text.contains('>') || text.trim().is_empty(),
            "raw `>` in {text:?}"
        );
        for (i, _) in text.match_indices('&') {
            let entity = &text[i..];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&#"]
                    .iter()
                    .any(|e| entity.starts_with(e)),
                "bare `&` in {text:?}"
            );
        }
    }

    #[test]
    fn svg_is_well_formed_and_names_every_node_and_edge() {
        let drawing = sample();
        let svg = svg(&drawing);
        assert_well_formed(&svg);
        assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
        for n in &drawing.nodes {
            assert!(
                svg.contains(&format!(">{}</text>", escape(&n.label))),
                "{}",
                n.id
            );
        }
        for e in &drawing.edges {
            assert!(
                svg.contains(&format!(">{}</text>", escape(&e.label))),
                "{}",
                e.label
            );
        }
        assert!(svg.contains(">core-a</text>") && svg.contains(">core-b</text>"));
        assert!(svg.contains("stroke-dasharray=\"2 3\""), "dotted edge");
        assert!(svg.contains("stroke-dasharray=\"6 4\""), "dashed edge");
        assert_eq!(svg.matches("marker-end=\"url(#peppy-arrow)\"").count(), 7);
    }

    #[test]
    fn node_boxes_do_not_overlap() {
        // A wider stack: three clusters, fan-in, fan-out and a long edge.
        let mut drawing = sample();
        for i in 0..8 {
            let cluster = ["core-a", "core-b", "core-c"][i % 3];
            drawing.nodes.push(node(
                &format!("n{i}"),
                "some_node:v1",
                Some(cluster),
                NodeState::Up,
            ));
            let from = if i == 0 {
                "arm".to_string()
            } else {
                format!("n{}", i / 2)
            };
            drawing
                .edges
                .push(edge(&from, &format!("n{i}"), "x", EdgeStyle::Solid));
        }
        drawing
            .edges
            .push(edge("arm", "n7", "long", EdgeStyle::Solid));
        let layout = layout(&drawing, 0.0);

        for (i, a) in layout.boxes.iter().enumerate() {
            for b in &layout.boxes[i + 1..] {
                assert!(!a.overlaps(b), "{a:?} overlaps {b:?}");
            }
        }
        // Frames do not overlap each other either, and each holds its members.
        for (i, (_, a)) in layout.frames.iter().enumerate() {
            for (_, b) in &layout.frames[i + 1..] {
                assert!(!a.overlaps(b), "frames {a:?} and {b:?}");
            }
        }
        for (n, r) in drawing.nodes.iter().zip(&layout.boxes) {
            if let Some(c) = &n.cluster {
                let (_, f) = layout.frames.iter().find(|(name, _)| name == c).unwrap();
                assert!(
                    f.x <= r.x && r.right() <= f.right() && f.y <= r.y && r.bottom() <= f.bottom()
                );
            }
        }
        assert_eq!(layout.frames.len(), 3);
    }

    #[test]
    fn layers_are_longest_paths_and_a_cycle_is_broken() {
        let drawing = Drawing {
            title: "t".into(),
            nodes: ["a", "b", "c"]
                .map(|id| node(id, "", None, NodeState::Planned))
                .to_vec(),
            edges: vec![
                edge("a", "b", "", EdgeStyle::Solid),
                edge("b", "c", "", EdgeStyle::Solid),
                edge("a", "c", "", EdgeStyle::Solid),
                edge("c", "a", "back", EdgeStyle::Solid),
            ],
        };
        let layout = layout(&drawing, 0.0);
        assert_eq!(layout.layer, vec![0, 1, 2]);
        assert!(layout.boxes[0].right() < layout.boxes[1].x);
        assert!(layout.boxes[1].right() < layout.boxes[2].x);
        assert_well_formed(&svg(&drawing));
    }

    #[test]
    fn the_arm_loop_lays_out_in_two_columns_with_labels_apart() {
        let drawing = sample();
        let layout = layout(&drawing, 0.0);
        assert_ne!(layout.layer[0], layout.layer[1], "arm and controller");
        let spots = label_spots(&drawing, &layout, &curves(&layout));
        let labels: Vec<Rect> = spots
            .iter()
            .zip(&drawing.edges)
            .map(|(at, e)| label_rect(&e.label, at.unwrap()))
            .collect();
        for (i, a) in labels.iter().enumerate() {
            for b in &labels[i + 1..] {
                assert!(!a.overlaps(b), "labels {a:?} and {b:?}");
            }
            for r in &layout.boxes {
                assert!(!a.overlaps(r), "label {a:?} on box {r:?}");
            }
        }
    }

    #[test]
    fn parallel_edges_and_self_loops_get_distinct_paths() {
        let svg = svg(&sample());
        let paths: Vec<&str> = svg
            .split("<path d=\"")
            .skip(1)
            .map(|p| &p[..p.find('"').unwrap()])
            .collect();
        let mut unique = paths.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), paths.len(), "{paths:#?}");
        let layout = layout(&sample(), 0.0);
        let curves = curves(&layout);
        // The two self-loops' labels sit at different heights.
        // Arrowheads arriving at one box land on distinct points.
        let into_recon: Vec<Point> = [2, 3, 6].map(|e| curves[e].unwrap().0[3]).to_vec();
        assert!(into_recon.windows(2).all(|w| w[0] != w[1]) && into_recon[0] != into_recon[2]);
        let (l1, l2) = (curves[4].unwrap().mid(), curves[5].unwrap().mid());
        assert!((l1.1 - l2.1).abs() >= LABEL_H);
        assert!(
            l1.1 < layout.boxes[3].y && l2.1 < layout.boxes[3].y,
            "loops above the box"
        );
    }

    #[test]
    fn text_is_escaped_everywhere() {
        let drawing = Drawing {
            title: "a<b>&\"c\"".into(),
            nodes: vec![
                node("x<&\"", "d<&\"", Some("c<&\""), NodeState::Planned),
                node("y", "", None, NodeState::Planned),
            ],
            edges: vec![edge("x<&\"", "y", "l<&\"'", EdgeStyle::Solid)],
        };
        for out in [svg(&drawing), html(&drawing)] {
            assert_well_formed(&out);
            assert!(out.contains("x&lt;&amp;&quot;"));
            assert!(out.contains("l&lt;&amp;&quot;&#39;"));
            assert!(!out.contains("x<&"));
        }
        assert!(dot(&drawing).contains(r#""x<&\"" -> "y" [label="l<&\"'"];"#));
    }

    #[test]
    fn an_empty_drawing_renders() {
        let drawing = Drawing::default();
        assert_well_formed(&svg(&drawing));
        assert_well_formed(&html(&drawing));
        assert_eq!(
            dot(&drawing),
            "digraph \"\" {\n  rankdir=LR;\n  node [shape=box, fontname=\"monospace\"];\n}\n"
        );
    }

    #[test]
    fn an_edge_to_an_unknown_node_is_listed_but_not_drawn() {
        let mut drawing = sample();
        drawing
            .edges
            .push(edge("ghost", "arm", "haunts", EdgeStyle::Solid));
        let svg = svg(&drawing);
        assert_well_formed(&svg);
        assert!(!svg.contains("haunts"));
        assert!(html(&drawing).contains("<td>ghost</td><td>arm</td><td>haunts</td>"));
    }

    #[test]
    fn output_is_deterministic() {
        let drawing = sample();
        assert_eq!(svg(&drawing), svg(&drawing.clone()));
        assert_eq!(html(&drawing), html(&drawing.clone()));
    }

    #[test]
    fn html_is_standalone_and_tabulates_edges_and_nodes() {
        let drawing = sample();
        let html = html(&drawing);
        assert_well_formed(&html);
        assert!(html.starts_with("<!DOCTYPE html>"));
        assert!(html.contains("<title>robot_arm_loop</title>"));
        assert!(html.contains("<h1>robot_arm_loop</h1>"));
        assert_eq!(html.matches("<svg ").count(), 1);
        for resource in ["<script", "<link", "src=", "href=", "@import"] {
            assert!(!html.contains(resource), "{resource}");
        }
        assert!(html.contains("<td>arm</td><td>controller</td><td>robot_arm</td>"));
        assert!(
            html.contains("<td>cam</td><td>realsense_d405:v1</td><td>down</td><td>core-b</td>")
        );
        assert!(html.contains("<h2>Edges (7)</h2>") && html.contains("<h2>Nodes (5)</h2>"));
    }

    #[test]
    fn dot_keeps_the_static_graph_format_and_frames_clusters() {
        let drawing = Drawing {
            title: "stack".into(),
            nodes: vec![
                node("cam", "realsense_d405:v1", None, NodeState::Planned),
                node("mosaic.extras.any", "", None, NodeState::Placeholder),
                node(
                    "mosaic",
                    "camera_mosaic:v1",
                    Some("core"),
                    NodeState::Planned,
                ),
            ],
            edges: vec![
                edge("cam", "mosaic", "left_cam", EdgeStyle::Solid),
                edge(
                    "mosaic.extras.any",
                    "mosaic",
                    "extras (any)",
                    EdgeStyle::Dashed,
                ),
                edge("mosaic", "cam", "t (external)", EdgeStyle::Dotted),
            ],
        };
        assert_eq!(
            dot(&drawing),
            r#"digraph "stack" {
  rankdir=LR;
  node [shape=box, fontname="monospace"];
  "cam" [label="cam\nrealsense_d405:v1"];
  "mosaic.extras.any" [label="mosaic.extras.any", shape=ellipse, style=dashed];
  subgraph "cluster_core" {
    label="core";
    "mosaic" [label="mosaic\ncamera_mosaic:v1"];
  }
  "cam" -> "mosaic" [label="left_cam"];
  "mosaic.extras.any" -> "mosaic" [label="extras (any)", style=dashed];
  "mosaic" -> "cam" [label="t (external)", style=dotted];
}
"#
        );
    }
}
