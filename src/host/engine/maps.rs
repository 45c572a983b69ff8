//! The host's maps: the merged map fed with every drone's scans, copies of a drone's map or of
//! the merged one for the API, scans sent over the API, and the changed regions for clients.
//!
//! In: [`FleetMap`] (set at start), scans from the API. Out: [`MapView`]s, `map_update`
//! [`HostEvent`]s (the runtime decides how often to take them).

use super::{Host, HostError, MapView};
use crate::host::status::HostEvent;
use crate::mapping::merged::FleetMap;
use crate::mapping::scan::RangeScan;
use crate::mission::Limits;

/// Most API scans waiting for one drone's next tick.
const MAX_QUEUED_SCANS: usize = 64;

fn mapping_off() -> HostError {
    HostError::NotSupported("mapping is off ([map] plugin = \"none\")".into())
}

impl Host {
    /// Keeps the fleet's merged map, fed with every drone's scans.
    pub fn set_map(&mut self, map: FleetMap) {
        self.map = Some(map);
        self.exploration.resync();
    }

    pub fn map(&self) -> Option<&FleetMap> {
        self.map.as_ref()
    }

    /// What missions are checked against (speed limit, geofence).
    pub fn limits(&self) -> &Limits {
        self.executors.limits()
    }

    /// The merged map's regions changed since the last call, as `map_update` events.
    pub fn take_map_updates(&mut self) -> Vec<HostEvent> {
        self.map
            .as_mut()
            .map(|m| {
                m.take_patches()
                    .into_iter()
                    .map(HostEvent::map_update)
                    .collect()
            })
            .unwrap_or_default()
    }

    /// A copy of the map `drone` plans on, or of the merged map.
    pub fn map_view(&self, drone: Option<&str>) -> Result<MapView, HostError> {
        match drone {
            Some(d) => {
                let i = self.route(Some(d))?;
                let map = self
                    .cores
                    .get(i)
                    .and_then(|c| c.map())
                    .ok_or_else(mapping_off)?;
                Ok(MapView::of_drone(d, map))
            }
            None => Ok(MapView::merged(self.map.as_ref().ok_or_else(mapping_off)?)),
        }
    }

    /// Queues scans from the API for the drone's next tick; answers how many.
    pub fn queue_scans(
        &mut self,
        drone: Option<&str>,
        scans: Vec<RangeScan>,
    ) -> Result<usize, HostError> {
        let i = self.route(drone)?;
        if self.cores.get(i).and_then(|c| c.map()).is_none() {
            return Err(mapping_off());
        }
        let queue = self
            .api_scans
            .get_mut(i)
            .ok_or_else(|| HostError::UnknownDrone(i.to_string(), String::new()))?;
        if queue.len() + scans.len() > MAX_QUEUED_SCANS {
            return Err(HostError::Unavailable(format!(
                "more than {MAX_QUEUED_SCANS} scans wait for the next tick; send fewer"
            )));
        }
        let n = scans.len();
        queue.extend(scans);
        Ok(n)
    }
}
