//! What a core gets from its fleet each tick: the fleet view (`types::FleetView`, the same
//! snapshot for every core of the host).
//!
//! In: filled by the host once per tick, before the cores tick. Out: read by the core, which
//! hands it to its behaviors' context and its safety stage.

use crate::types::FleetView;
use std::sync::Arc;

/// What a core gets from its fleet each tick: the view (shared by every core of the host) and
/// the fleet's merged map to register its scans against (`None`: no map, no correction).
#[derive(Clone, Copy)]
pub struct FleetInput<'a> {
    pub view: &'a Arc<FleetView>,
    pub map: Option<crate::mapping::registration::Reference<'a>>,
}
