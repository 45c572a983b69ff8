//! AFL entry point for [`kestrel_fuzz::scans`]; see `fuzz/README.md`.

fn main() {
    afl::fuzz!(|data: &[u8]| kestrel_fuzz::scans(data));
}
