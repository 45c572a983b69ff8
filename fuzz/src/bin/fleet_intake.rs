//! AFL entry point for [`kestrel_fuzz::fleet_intake`]; see `fuzz/README.md`.

fn main() {
    afl::fuzz!(|data: &[u8]| kestrel_fuzz::fleet_intake(data));
}
