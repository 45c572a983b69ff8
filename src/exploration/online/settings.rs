//! The tuned weights of exploration in one place: the `kestrel` allocator's scores and the rule
//! that says which small unknown regions are worth a trip.
//!
//! In: the config's `[exploration]` section (the fleet's defaults) and, per drone, the
//! `settings` of its `explore` goal ([`SettingsOverride`]: any field given there replaces the
//! section's). Out: a validated [`ExplorationSettings`], carried in each
//! [`super::service::ExploreRequest`] to the allocator. Every field has a unit in its name and a
//! documented range; [`ExplorationSettings::validate`] refuses a value outside it with an error
//! naming the field and its unit. The defaults are the values measured best so far
//! (BENCHMARKS.md).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The exploration's weights (config `[exploration]`, the `explore` goal's `settings`). All
/// distances are metres of flown path, so a score reads as "worth this many metres of detour".
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ExplorationSettings {
    /// `kestrel`: bonus per metre of frontier length, up to `size_bonus_cap_m` (m of path per
    /// m, 0..=10; default 1).
    pub size_bonus_per_m: f64,
    /// `kestrel`: longest frontier the size bonus counts (m, 0..=50; default 3.5).
    pub size_bonus_cap_m: f64,
    /// `kestrel`: penalty for a frontier at another drone's goal, falling linearly to nothing
    /// at `others_radius_m` from it (m, 0..=100; default 12; 0 turns the rule off).
    pub others_penalty_m: f64,
    /// `kestrel`: how far from another drone's goal its penalty reaches (m, 0.1..=50; default
    /// 8, about two beam ranges).
    pub others_radius_m: f64,
    /// `kestrel`: penalty per metre by which another drone, going on from its goal, would
    /// reach a frontier before this one (m per m, 0..=10; default 1; 0 turns the rule off).
    pub behind_penalty_per_m: f64,
    /// `kestrel`: bonus for keeping the current goal, against dithering between two equal
    /// frontiers (m, 0..=50; default 2).
    pub keep_bonus_m: f64,
    /// `kestrel`: a frontier whose goal lies this close to the current goal is still it (m,
    /// 0..=10; default 1).
    pub keep_radius_m: f64,
    /// `kestrel`: bonus for a frontier at the map's edge, falling linearly to nothing at
    /// `edge_radius_m` from it (m, 0..=50; default 8; 0 turns the edge rule off).
    pub edge_bonus_m: f64,
    /// `kestrel`: how far from the map's edge the edge bonus reaches (m, 0.1..=50; default 5).
    pub edge_radius_m: f64,
    /// Every allocator: a frontier bordering less unknown than this is a pocket (behind a
    /// pole, in a corner), flown to only from `low_gain_near_m` and left out of the end rule
    /// (m^2, 0..=100; default 0.5; 0: no frontier is a pocket). Half a square metre is 0.02 %
    /// of the thesis's 50 x 50 m world, and the watch at a pocket that never clears (a quarter
    /// turn and more) took the end of every run.
    pub pocket_area_m2: f64,
    /// Every allocator: a frontier bordering at least this much unknown is worth a trip from
    /// anywhere; smaller ones only from `low_gain_near_m` plus `trip_m_per_m2` for each m^2
    /// of it (m^2, 0..=1000; default 4; 0: every frontier is worth any trip).
    pub worth_any_trip_m2: f64,
    /// Every allocator: pockets are flown to from at most this far (m of path, 0..=100;
    /// default 3).
    pub low_gain_near_m: f64,
    /// Every allocator: the trip a small unknown region is worth grows by this much per m^2 of
    /// it (m of path per m^2, 0..=100; default 8).
    pub trip_m_per_m2: f64,
}

impl Default for ExplorationSettings {
    fn default() -> Self {
        Self {
            size_bonus_per_m: 1.0,
            size_bonus_cap_m: 3.5,
            others_penalty_m: 12.0,
            others_radius_m: 8.0,
            behind_penalty_per_m: 1.0,
            keep_bonus_m: 2.0,
            keep_radius_m: 1.0,
            edge_bonus_m: 8.0,
            edge_radius_m: 5.0,
            pocket_area_m2: 0.5,
            worth_any_trip_m2: 4.0,
            low_gain_near_m: 3.0,
            trip_m_per_m2: 8.0,
        }
    }
}

/// A field outside its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field} must be within {min}..={max} {unit}, got {value}")]
pub struct SettingsError {
    pub field: &'static str,
    pub value: f64,
    pub min: f64,
    pub max: f64,
    pub unit: &'static str,
}

/// One field as validation sees it: name, value, range and unit.
struct Field {
    name: &'static str,
    value: f64,
    range: (f64, f64),
    unit: &'static str,
}

const fn field(name: &'static str, value: f64, range: (f64, f64), unit: &'static str) -> Field {
    Field {
        name,
        value,
        range,
        unit,
    }
}

impl ExplorationSettings {
    /// Every field with its range (the one its doc states) and unit.
    fn fields(&self) -> [Field; 13] {
        [
            field(
                "size_bonus_per_m",
                self.size_bonus_per_m,
                (0.0, 10.0),
                "m per m",
            ),
            field("size_bonus_cap_m", self.size_bonus_cap_m, (0.0, 50.0), "m"),
            field("others_penalty_m", self.others_penalty_m, (0.0, 100.0), "m"),
            field("others_radius_m", self.others_radius_m, (0.1, 50.0), "m"),
            field(
                "behind_penalty_per_m",
                self.behind_penalty_per_m,
                (0.0, 10.0),
                "m per m",
            ),
            field("keep_bonus_m", self.keep_bonus_m, (0.0, 50.0), "m"),
            field("keep_radius_m", self.keep_radius_m, (0.0, 10.0), "m"),
            field("edge_bonus_m", self.edge_bonus_m, (0.0, 50.0), "m"),
            field("edge_radius_m", self.edge_radius_m, (0.1, 50.0), "m"),
            field("pocket_area_m2", self.pocket_area_m2, (0.0, 100.0), "m^2"),
            field(
                "worth_any_trip_m2",
                self.worth_any_trip_m2,
                (0.0, 1000.0),
                "m^2",
            ),
            field("low_gain_near_m", self.low_gain_near_m, (0.0, 100.0), "m"),
            field(
                "trip_m_per_m2",
                self.trip_m_per_m2,
                (0.0, 100.0),
                "m per m^2",
            ),
        ]
    }

    /// Every field finite and within its range; the first that is not, named with its unit.
    pub fn validate(&self) -> Result<(), SettingsError> {
        for f in self.fields() {
            let (min, max) = f.range;
            if !(f.value.is_finite() && (min..=max).contains(&f.value)) {
                return Err(SettingsError {
                    field: f.name,
                    value: f.value,
                    min,
                    max,
                    unit: f.unit,
                });
            }
        }
        Ok(())
    }

    /// These settings with the fields `over` gives replaced.
    pub fn with(mut self, over: &SettingsOverride) -> Self {
        let pairs = [
            (&mut self.size_bonus_per_m, over.size_bonus_per_m),
            (&mut self.size_bonus_cap_m, over.size_bonus_cap_m),
            (&mut self.others_penalty_m, over.others_penalty_m),
            (&mut self.others_radius_m, over.others_radius_m),
            (&mut self.behind_penalty_per_m, over.behind_penalty_per_m),
            (&mut self.keep_bonus_m, over.keep_bonus_m),
            (&mut self.keep_radius_m, over.keep_radius_m),
            (&mut self.edge_bonus_m, over.edge_bonus_m),
            (&mut self.edge_radius_m, over.edge_radius_m),
            (&mut self.pocket_area_m2, over.pocket_area_m2),
            (&mut self.worth_any_trip_m2, over.worth_any_trip_m2),
            (&mut self.low_gain_near_m, over.low_gain_near_m),
            (&mut self.trip_m_per_m2, over.trip_m_per_m2),
        ];
        for (field, given) in pairs {
            if let Some(v) = given {
                *field = v;
            }
        }
        self
    }
}

/// The `explore` goal's `settings`: any field of [`ExplorationSettings`] (same name, unit and
/// range), replacing the config's `[exploration]` value for this drone; a field left out keeps
/// the config's.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SettingsOverride {
    /// Bonus per metre of frontier length (m per m, 0..=10).
    pub size_bonus_per_m: Option<f64>,
    /// Longest frontier the size bonus counts (m, 0..=50).
    pub size_bonus_cap_m: Option<f64>,
    /// Penalty at another drone's goal (m, 0..=100; 0: off).
    pub others_penalty_m: Option<f64>,
    /// Reach of that penalty (m, 0.1..=50).
    pub others_radius_m: Option<f64>,
    /// Penalty per metre another drone would be there first (m per m, 0..=10).
    pub behind_penalty_per_m: Option<f64>,
    /// Bonus for keeping the current goal (m, 0..=50).
    pub keep_bonus_m: Option<f64>,
    /// A goal this close to the current one is still it (m, 0..=10).
    pub keep_radius_m: Option<f64>,
    /// Bonus at the map's edge (m, 0..=50; 0 turns the edge rule off).
    pub edge_bonus_m: Option<f64>,
    /// Reach of the edge bonus (m, 0.1..=50).
    pub edge_radius_m: Option<f64>,
    /// Less unknown than this behind a frontier makes it a pocket (m^2, 0..=100).
    pub pocket_area_m2: Option<f64>,
    /// This much unknown behind a frontier is worth any trip (m^2, 0..=1000).
    pub worth_any_trip_m2: Option<f64>,
    /// Pockets are flown to from at most this far (m of path, 0..=100).
    pub low_gain_near_m: Option<f64>,
    /// Trip a small region is worth per m^2 of it (m of path per m^2, 0..=100).
    pub trip_m_per_m2: Option<f64>,
}

impl SettingsOverride {
    /// Every field given is within its range (checked over the defaults: the ranges do not
    /// depend on one another).
    pub fn validate(&self) -> Result<(), SettingsError> {
        ExplorationSettings::default().with(self).validate()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_defaults_are_valid_and_a_value_out_of_range_is_named_with_its_unit() {
        ExplorationSettings::default().validate().unwrap();
        let bad = ExplorationSettings {
            edge_radius_m: 0.0,
            ..ExplorationSettings::default()
        };
        let e = bad.validate().unwrap_err();
        assert_eq!(e.field, "edge_radius_m");
        assert_eq!(
            e.to_string(),
            "edge_radius_m must be within 0.1..=50 m, got 0"
        );
        let nan = ExplorationSettings {
            trip_m_per_m2: f64::NAN,
            ..ExplorationSettings::default()
        };
        assert!(nan
            .validate()
            .unwrap_err()
            .to_string()
            .contains("m per m^2"));
    }

    #[test]
    fn an_override_replaces_only_the_fields_it_gives() {
        let config = ExplorationSettings {
            keep_bonus_m: 3.0,
            ..ExplorationSettings::default()
        };
        let over: SettingsOverride = serde_json::from_str(r#"{"edge_bonus_m": 0}"#).unwrap();
        let s = config.with(&over);
        assert_eq!(s.edge_bonus_m, 0.0);
        assert_eq!(s.keep_bonus_m, 3.0, "the config's, not the default");
        assert_eq!(s.with(&SettingsOverride::default()), s);
        let bad: SettingsOverride = serde_json::from_str(r#"{"keep_radius_m": -1}"#).unwrap();
        assert_eq!(bad.validate().unwrap_err().field, "keep_radius_m");
        assert!(serde_json::from_str::<SettingsOverride>(r#"{"edge_bonus": 0}"#).is_err());
    }

    #[test]
    fn the_toml_section_takes_any_subset_of_the_fields() {
        let s: ExplorationSettings = toml::from_str("edge_bonus_m = 0.0").unwrap();
        assert_eq!(s.edge_bonus_m, 0.0);
        assert_eq!(s.others_penalty_m, 12.0);
        assert!(toml::from_str::<ExplorationSettings>("edge_bonus = 0.0").is_err());
    }
}
