//! AFL entry point for [`kestrel_fuzz::mavlink`]; see `fuzz/README.md`.

fn main() {
    afl::fuzz!(|data: &[u8]| kestrel_fuzz::mavlink(data));
}
