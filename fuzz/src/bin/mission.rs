//! AFL entry point for [`kestrel_fuzz::mission`]; see `fuzz/README.md`.

fn main() {
    afl::fuzz!(|data: &[u8]| kestrel_fuzz::mission(data));
}
