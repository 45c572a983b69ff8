//! Topological graph plugin: named nodes at ENU positions joined by weighted, undirected edges.
//!
//! In: an indoor-farm description ([`FarmSpec`]) or graph JSON. Out: a validated [`TopoGraph`]
//! with an adjacency list for the graph planner, and its JSON form.
//!
//! Farm layout (x east along the beds, y north across the rows): `rows` rows of beds separated
//! and bordered by aisles of `aisle_width_m` (so `rows + 1` aisles), with a head corridor of the
//! same width at both ends. Each aisle gets one node per bed (at the bed's centre, where a drone
//! inspects the beds on both sides) plus a node at each end; the end nodes of neighbouring aisles
//! are joined through the head corridors. Stacked levels repeat the graph at each height and join
//! levels at the aisle ends. Node ids: `L{level}_A{aisle}_W` (west end), `L{level}_A{aisle}_B{bed}`
//! and `L{level}_A{aisle}_E` (east end), all counted from 0; edge weights are Euclidean lengths.

use std::collections::HashMap;

use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::MapError;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphNode {
    pub id: String,
    pub position_enu_m: Vector3<f64>,
}

/// Undirected edge between two node ids.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphEdge {
    pub from: String,
    pub to: String,
    /// Traversal cost (>= 0); in files it defaults to the Euclidean length in metres.
    pub weight: f64,
}

/// Edge as read from a file: the weight may be omitted.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EdgeJson {
    from: String,
    to: String,
    #[serde(default)]
    weight: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GraphJson {
    nodes: Vec<GraphNode>,
    edges: Vec<EdgeJson>,
}

/// A validated graph. Nodes are addressed by their position in `nodes()` in the planner.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "GraphJson")]
pub struct TopoGraph {
    nodes: Vec<GraphNode>,
    edges: Vec<GraphEdge>,
    #[serde(skip)]
    adjacency: Vec<Vec<(usize, f64)>>,
}

impl TryFrom<GraphJson> for TopoGraph {
    type Error = MapError;
    fn try_from(raw: GraphJson) -> Result<Self, MapError> {
        let index: HashMap<&str, &GraphNode> =
            raw.nodes.iter().map(|n| (n.id.as_str(), n)).collect();
        let mut edges = Vec::with_capacity(raw.edges.len());
        for e in raw.edges {
            let weight = match e.weight {
                Some(w) => w,
                None => match (index.get(e.from.as_str()), index.get(e.to.as_str())) {
                    (Some(a), Some(b)) => (a.position_enu_m - b.position_enu_m).norm(),
                    _ => {
                        return Err(MapError::Graph(format!(
                            "edge {}-{}: unknown node",
                            e.from, e.to
                        )))
                    }
                },
            };
            edges.push(GraphEdge {
                from: e.from,
                to: e.to,
                weight,
            });
        }
        TopoGraph::new(raw.nodes, edges)
    }
}

impl TopoGraph {
    /// Validates ids (unique, edges refer to known nodes), positions and weights (finite, >= 0).
    pub fn new(nodes: Vec<GraphNode>, edges: Vec<GraphEdge>) -> Result<Self, MapError> {
        let mut index = HashMap::with_capacity(nodes.len());
        for (i, n) in nodes.iter().enumerate() {
            let p = &n.position_enu_m;
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                return Err(MapError::Graph(format!(
                    "node {}: position not finite",
                    n.id
                )));
            }
            if index.insert(n.id.as_str(), i).is_some() {
                return Err(MapError::Graph(format!("duplicate node id {}", n.id)));
            }
        }
        let mut adjacency = vec![Vec::new(); nodes.len()];
        for e in &edges {
            let (Some(&a), Some(&b)) = (index.get(e.from.as_str()), index.get(e.to.as_str()))
            else {
                return Err(MapError::Graph(format!(
                    "edge {}-{}: unknown node",
                    e.from, e.to
                )));
            };
            if !(e.weight.is_finite() && e.weight >= 0.0) {
                return Err(MapError::Graph(format!(
                    "edge {}-{}: bad weight",
                    e.from, e.to
                )));
            }
            if let Some(l) = adjacency.get_mut(a) {
                l.push((b, e.weight));
            }
            if let Some(l) = adjacency.get_mut(b) {
                l.push((a, e.weight));
            }
        }
        Ok(TopoGraph {
            nodes,
            edges,
            adjacency,
        })
    }

    pub fn nodes(&self) -> &[GraphNode] {
        &self.nodes
    }

    pub fn edges(&self) -> &[GraphEdge] {
        &self.edges
    }

    /// Position in `nodes()` of an id.
    pub fn node_index(&self, id: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.id == id)
    }

    /// Neighbours of a node index with edge weights (empty for a bad index).
    pub fn neighbors(&self, node: usize) -> &[(usize, f64)] {
        self.adjacency.get(node).map_or(&[], Vec::as_slice)
    }

    /// Index of the node nearest (3D Euclidean) to a point, `None` for an empty graph.
    pub fn nearest_node(&self, p: &Vector3<f64>) -> Option<usize> {
        self.nodes
            .iter()
            .enumerate()
            .min_by(|a, b| {
                let da = (a.1.position_enu_m - p).norm_squared();
                let db = (b.1.position_enu_m - p).norm_squared();
                da.total_cmp(&db)
            })
            .map(|(i, _)| i)
    }

    pub fn to_json(&self) -> String {
        // Serialising plain strings and finite floats cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    pub fn from_json(text: &str) -> Result<Self, MapError> {
        serde_json::from_str(text).map_err(|e| MapError::Graph(e.to_string()))
    }

    /// Builds the indoor-farm graph described in the module docs.
    pub fn from_indoor_farm(farm: &FarmSpec) -> Result<Self, MapError> {
        farm.validate()?;
        let mut nodes: Vec<GraphNode> = Vec::new();
        let mut edges = Vec::new();
        let mut position: HashMap<String, Vector3<f64>> = HashMap::new();
        let mut edge = |position: &HashMap<String, Vector3<f64>>, a: &str, b: &str| {
            if let (Some(pa), Some(pb)) = (position.get(a), position.get(b)) {
                edges.push(GraphEdge {
                    from: a.to_owned(),
                    to: b.to_owned(),
                    weight: (pa - pb).norm(),
                });
            }
        };
        let aisles = farm.rows + 1;
        for (l, &z) in farm.level_heights_m.iter().enumerate() {
            for a in 0..aisles {
                let chain: Vec<String> = std::iter::once(format!("L{l}_A{a}_W"))
                    .chain((0..farm.beds_per_row).map(|b| format!("L{l}_A{a}_B{b}")))
                    .chain(std::iter::once(format!("L{l}_A{a}_E")))
                    .collect();
                for (k, id) in chain.iter().enumerate() {
                    let xy = farm.aisle_point(a, k);
                    let p = Vector3::new(xy.x, xy.y, z);
                    position.insert(id.clone(), p);
                    nodes.push(GraphNode {
                        id: id.clone(),
                        position_enu_m: p,
                    });
                }
                for pair in chain.windows(2) {
                    edge(&position, &pair[0], &pair[1]);
                }
                if a > 0 {
                    for end in ["W", "E"] {
                        edge(
                            &position,
                            &format!("L{l}_A{}_{end}", a - 1),
                            &format!("L{l}_A{a}_{end}"),
                        );
                    }
                }
                if l > 0 {
                    for end in ["W", "E"] {
                        edge(
                            &position,
                            &format!("L{}_A{a}_{end}", l - 1),
                            &format!("L{l}_A{a}_{end}"),
                        );
                    }
                }
            }
        }
        TopoGraph::new(nodes, edges)
    }
}

/// An indoor vertical farm (see the module docs for the layout).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FarmSpec {
    /// Number of bed rows (>= 1).
    pub rows: u32,
    /// Beds along each row (>= 1).
    pub beds_per_row: u32,
    /// Bed extent along the row (x), metres.
    pub bed_length_m: f64,
    /// Bed extent across the row (y), metres.
    pub bed_width_m: f64,
    /// Width of the aisles and head corridors, metres.
    pub aisle_width_m: f64,
    /// South-west corner of the farm (ENU, metres).
    pub origin_enu_m: Vector2<f64>,
    /// Flight height of each level (ENU z, metres); at least one.
    pub level_heights_m: Vec<f64>,
}

impl FarmSpec {
    fn validate(&self) -> Result<(), MapError> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if self.rows == 0 || self.beds_per_row == 0 {
            return Err(MapError::Farm("rows and beds_per_row must be >= 1".into()));
        }
        if self.rows > 1000 || self.beds_per_row > 1000 || self.level_heights_m.len() > 100 {
            return Err(MapError::Farm(
                "farm too large (1000 rows/beds, 100 levels)".into(),
            ));
        }
        if !(positive(self.bed_length_m)
            && positive(self.bed_width_m)
            && positive(self.aisle_width_m))
        {
            return Err(MapError::Farm("bed and aisle sizes must be > 0".into()));
        }
        if self.level_heights_m.is_empty() || !self.level_heights_m.iter().all(|z| z.is_finite()) {
            return Err(MapError::Farm(
                "need at least one finite level height".into(),
            ));
        }
        if !(self.origin_enu_m.x.is_finite() && self.origin_enu_m.y.is_finite()) {
            return Err(MapError::Farm("origin not finite".into()));
        }
        Ok(())
    }

    /// Point `k` of aisle `a`: 0 = west end, 1..=beds = bed centres, beds + 1 = east end.
    fn aisle_point(&self, a: u32, k: usize) -> Vector2<f64> {
        let y = self.aisle_width_m / 2.0 + f64::from(a) * (self.aisle_width_m + self.bed_width_m);
        let beds = self.beds_per_row as usize;
        let x = if k == 0 {
            self.aisle_width_m / 2.0
        } else if k > beds {
            self.aisle_width_m * 1.5 + beds as f64 * self.bed_length_m
        } else {
            self.aisle_width_m + (k as f64 - 0.5) * self.bed_length_m
        };
        self.origin_enu_m + Vector2::new(x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn farm() -> FarmSpec {
        FarmSpec {
            rows: 2,
            beds_per_row: 3,
            bed_length_m: 2.0,
            bed_width_m: 1.0,
            aisle_width_m: 1.0,
            origin_enu_m: Vector2::new(10.0, 0.0),
            level_heights_m: vec![1.0, 2.5],
        }
    }

    #[test]
    fn farm_graph_has_expected_nodes_edges_and_positions() {
        let g = TopoGraph::from_indoor_farm(&farm()).unwrap();
        // 2 levels x 3 aisles x (3 beds + 2 ends) nodes.
        assert_eq!(g.nodes().len(), 30);
        // Per level: 3 aisles x 4 chain edges + 2 rows x 2 head edges = 16; 2 levels + 6 vertical.
        assert_eq!(g.edges().len(), 38);
        let b = g.node_index("L1_A2_B1").unwrap();
        // Aisle 2 centre y = 0.5 + 2 * 2.0; bed 1 centre x = 10 + 1 + 1.5 * 2.
        assert_eq!(g.nodes()[b].position_enu_m, Vector3::new(14.0, 4.5, 2.5));
        let e = g.node_index("L0_A0_E").unwrap();
        assert_eq!(g.nodes()[e].position_enu_m, Vector3::new(17.5, 0.5, 1.0));
        // The east end connects to the last bed (1.5 m), the next aisle's end (2 m), the level
        // above (1.5 m).
        let mut w: Vec<f64> = g.neighbors(e).iter().map(|&(_, w)| w).collect();
        w.sort_by(f64::total_cmp);
        assert_eq!(w, vec![1.5, 1.5, 2.0]);
    }

    #[test]
    fn json_round_trip_and_default_weights() {
        let g = TopoGraph::from_indoor_farm(&farm()).unwrap();
        let back = TopoGraph::from_json(&g.to_json()).unwrap();
        assert_eq!(back, g);
        let text = r#"{"nodes":[{"id":"a","position_enu_m":[0,0,1]},{"id":"b","position_enu_m":[3,4,1]}],
                       "edges":[{"from":"a","to":"b"}]}"#;
        let g = TopoGraph::from_json(text).unwrap();
        assert_eq!(g.edges()[0].weight, 5.0);
        assert_eq!(g.nearest_node(&Vector3::new(2.9, 3.0, 0.0)), Some(1));
    }

    #[test]
    fn bad_graphs_and_farms_are_refused() {
        let text =
            r#"{"nodes":[{"id":"a","position_enu_m":[0,0,1]}],"edges":[{"from":"a","to":"z"}]}"#;
        assert!(matches!(
            TopoGraph::from_json(text),
            Err(MapError::Graph(_))
        ));
        let dup = r#"{"nodes":[{"id":"a","position_enu_m":[0,0,1]},{"id":"a","position_enu_m":[1,0,1]}],"edges":[]}"#;
        assert!(TopoGraph::from_json(dup).is_err());
        let mut f = farm();
        f.rows = 0;
        assert!(matches!(
            TopoGraph::from_indoor_farm(&f),
            Err(MapError::Farm(_))
        ));
    }
}
