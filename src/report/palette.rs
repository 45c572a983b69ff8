//! Colours of the report's figures: one per behavior (the same in every figure and every
//! report, so a reader learns them once) and one per drone.
//!
//! In: a behavior name or a drone's index. Out: an RGB colour, and its `#RRGGBB` form as the
//! SVG files spell it.

use plotters::style::RGBColor;

/// Known behaviors first (Tableau 10 and its light half); others get one of the rest by name.
const BEHAVIORS: [(&str, RGBColor); 12] = [
    ("takeoff", RGBColor(0x1F, 0x77, 0xB4)),
    ("go_to", RGBColor(0xFF, 0x7F, 0x0E)),
    ("follow_path", RGBColor(0x2C, 0xA0, 0x2C)),
    ("navigate_to", RGBColor(0xD6, 0x27, 0x28)),
    ("land", RGBColor(0x94, 0x67, 0xBD)),
    ("rtl", RGBColor(0x8C, 0x56, 0x4B)),
    ("hover", RGBColor(0xE3, 0x77, 0xC2)),
    ("explore", RGBColor(0x17, 0xBE, 0xCF)),
    ("rotate", RGBColor(0xBC, 0xBD, 0x22)),
    ("point_gimbal", RGBColor(0x39, 0x3B, 0x79)),
    ("follow_reference", RGBColor(0xFF, 0xBB, 0x78)),
    ("take_photo", RGBColor(0x63, 0x79, 0x39)),
];

const OTHERS: [RGBColor; 6] = [
    RGBColor(0x98, 0xDF, 0x8A),
    RGBColor(0xFF, 0x98, 0x96),
    RGBColor(0xC5, 0xB0, 0xD5),
    RGBColor(0xC4, 0x9C, 0x94),
    RGBColor(0xDB, 0xDB, 0x8D),
    RGBColor(0x9E, 0xDA, 0xE5),
];

/// Poses with no motion behavior.
pub const NO_BEHAVIOR: RGBColor = RGBColor(0xA0, 0xA0, 0xA0);

const DRONES: [RGBColor; 8] = [
    RGBColor(0xE4, 0x1A, 0x1C),
    RGBColor(0x37, 0x7E, 0xB8),
    RGBColor(0x4D, 0xAF, 0x4A),
    RGBColor(0x98, 0x4E, 0xA3),
    RGBColor(0xFF, 0x7F, 0x00),
    RGBColor(0xA6, 0x56, 0x28),
    RGBColor(0xF7, 0x81, 0xBF),
    RGBColor(0x33, 0x33, 0x33),
];

pub fn behavior(name: Option<&str>) -> RGBColor {
    let Some(name) = name else {
        return NO_BEHAVIOR;
    };
    if let Some((_, c)) = BEHAVIORS.iter().find(|(n, _)| *n == name) {
        return *c;
    }
    let hash = name.bytes().fold(0usize, |h, b| {
        h.wrapping_mul(31).wrapping_add(usize::from(b))
    });
    OTHERS
        .get(hash % OTHERS.len())
        .copied()
        .unwrap_or(NO_BEHAVIOR)
}

pub fn drone(index: usize) -> RGBColor {
    DRONES
        .get(index % DRONES.len())
        .copied()
        .unwrap_or(NO_BEHAVIOR)
}

/// `#RRGGBB`, upper case, as plotters writes SVG colours.
pub fn hex(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

/// The colour of a behavior as it appears in the SVG files.
pub fn behavior_hex(name: &str) -> String {
    hex(behavior(Some(name)))
}
