//! AFL entry point for [`kestrel_fuzz::config`]; see `fuzz/README.md`.

fn main() {
    afl::fuzz!(|data: &[u8]| kestrel_fuzz::config(data));
}
