//! A validated plan item as the executor keeps it: its behavior, its method and arguments as
//! compact JSON text, and its options. The goal the behavior gets is derived again from the
//! text when the item starts (or is modified in flight), and on the store's thread when it is
//! saved: a loaded mission holds about its JSON's size, where one tree of `serde_json::Value`
//! per copy (as written, the goal, the parsed goal) held 40 to 100 times it (issue 29, item
//! 10; BENCHMARKS.md, "Memory of a stored mission").
//!
//! In: an item as written ([`MissionItem`]) and its options, or an item from a mission file.
//! Out: the item as written again, its goal, and the mission file's form (`item`, `goal`,
//! `options`, as before, so files of either form load in both).

use super::methods::canonicalize;
use super::model::{ItemOptions, MissionItem, CALL};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::{Map, Value};

/// Why an item's goal could not be derived again: its text is Kestrel's own, written from a
/// validated item, so only a mission file changed by hand gets here.
#[derive(Debug, thiserror::Error)]
pub enum ItemError {
    #[error("the item's text: {0}")]
    Text(#[from] serde_json::Error),
    #[error("the item's arguments: {0}")]
    Arguments(String),
}

/// A validated plan item.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanItem {
    /// The behavior's name, then `{"method", "args"}` as compact JSON, each left out when it
    /// is the default (`__call__`, no arguments), the object too when both are: one allocation,
    /// so that even the shortest item (`{"behavior":"land"}`) costs under three times its JSON.
    text: Box<str>,
    pub options: ItemOptions,
}

#[derive(Serialize)]
struct CallRef<'a> {
    #[serde(skip_serializing_if = "is_call")]
    method: &'a str,
    #[serde(skip_serializing_if = "Map::is_empty")]
    args: &'a Map<String, Value>,
}

fn is_call(method: &&str) -> bool {
    *method == CALL
}

#[derive(Deserialize)]
struct CallOwned {
    #[serde(default)]
    method: Option<String>,
    #[serde(default)]
    args: Map<String, Value>,
}

/// The mission file's form of an item (what older Kestrels wrote and read).
#[derive(Serialize, Deserialize)]
struct ItemFile {
    item: MissionItem,
    /// Derived from `item` when read: a file's goal is not trusted over its arguments.
    #[serde(default)]
    goal: Value,
    options: ItemOptions,
}

impl PlanItem {
    /// An item as written (validated) with its options.
    pub fn new(item: &MissionItem, options: ItemOptions) -> Result<Self, serde_json::Error> {
        if item.behavior.contains('{') {
            return Err(serde::de::Error::custom(format!(
                "`{}` is not a behavior name",
                item.behavior
            )));
        }
        let mut text = item.behavior.clone();
        if item.method != CALL || !item.args.is_empty() {
            text.push_str(&serde_json::to_string(&CallRef {
                method: &item.method,
                args: &item.args,
            })?);
        }
        Ok(Self {
            text: text.into_boxed_str(),
            options,
        })
    }

    pub fn behavior(&self) -> &str {
        self.split().0
    }

    /// The behavior's name and the call's JSON (empty for a plain `__call__`).
    fn split(&self) -> (&str, &str) {
        let at = self.text.find('{').unwrap_or(self.text.len());
        self.text.split_at(at)
    }

    /// The item as written (method defaults filled in).
    pub fn written(&self) -> Result<MissionItem, serde_json::Error> {
        let (behavior, call) = self.split();
        let call = if call.is_empty() {
            CallOwned {
                method: None,
                args: Map::new(),
            }
        } else {
            serde_json::from_str(call)?
        };
        Ok(MissionItem {
            behavior: behavior.to_string(),
            method: call.method.unwrap_or_else(|| CALL.to_string()),
            args: call.args,
        })
    }

    /// The goal its behavior gets: the method applied, the options taken out.
    pub fn goal(&self) -> Result<Value, ItemError> {
        let item = self.written()?;
        canonicalize(&item.behavior, &item.method, &item.args)
            .map(|c| Value::Object(c.goal))
            .map_err(|errors| {
                let said: Vec<String> = errors
                    .into_iter()
                    .map(|e| format!("{}: {}", e.key, e.message))
                    .collect();
                ItemError::Arguments(said.join("; "))
            })
    }
}

impl Serialize for PlanItem {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::Error;
        ItemFile {
            item: self.written().map_err(S::Error::custom)?,
            goal: self.goal().map_err(S::Error::custom)?,
            options: self.options,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for PlanItem {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let file = ItemFile::deserialize(d)?;
        PlanItem::new(&file.item, file.options).map_err(D::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn item(behavior: &str, method: &str, args: Value) -> MissionItem {
        serde_json::from_value(json!({"behavior": behavior, "method": method, "args": args}))
            .unwrap()
    }

    #[test]
    fn an_item_gives_back_what_was_written_and_its_goal() {
        let written = item(
            "go_to",
            "go_to_point_with_yaw",
            json!({"point": [1, 2.5, 3], "angle": 0.5, "speed": 1, "wait": false}),
        );
        let options = ItemOptions {
            wait: false,
            ..ItemOptions::default()
        };
        let kept = PlanItem::new(&written, options).unwrap();
        assert_eq!(kept.behavior(), "go_to");
        assert_eq!(kept.written().unwrap(), written);
        let goal = kept.goal().unwrap();
        assert_eq!(goal["x"], json!(1));
        assert_eq!(goal["yaw_angle"], json!(0.5));
        assert!(goal.get("wait").is_none(), "{goal}");
    }

    #[test]
    fn a_call_without_arguments_keeps_no_text() {
        let kept = PlanItem::new(&item("land", CALL, json!({})), ItemOptions::default()).unwrap();
        assert_eq!(&*kept.text, "land");
        assert_eq!(kept.written().unwrap().method, CALL);
    }

    /// The file form is the one older Kestrels wrote (`item`, `goal`, `options`): it reads back
    /// to the same item, and an old file's goal is derived again, not taken.
    #[test]
    fn the_file_form_is_unchanged_and_reads_back() {
        let written = item("hover", "hover", json!({"duration": 2}));
        let kept = PlanItem::new(&written, ItemOptions::default()).unwrap();
        let file = serde_json::to_value(&kept).unwrap();
        assert_eq!(file["item"], serde_json::to_value(&written).unwrap());
        assert_eq!(file["goal"], kept.goal().unwrap());
        assert_eq!(
            file["options"],
            serde_json::to_value(ItemOptions::default()).unwrap()
        );
        let back: PlanItem = serde_json::from_value(file).unwrap();
        assert_eq!(back, kept);
    }

    #[test]
    fn a_name_that_could_not_be_told_from_its_call_is_refused() {
        let odd = item("go_to{", CALL, json!({}));
        assert!(PlanItem::new(&odd, ItemOptions::default()).is_err());
    }
}
