//! Where the host keeps its state on a vehicle: the state directory chosen from the flag, the
//! environment systemd sets and the config.

use crate::config::Config;

/// The state directory: `--state-dir`, else `$STATE_DIRECTORY` (set by systemd), else the
/// config's `[mission] state_dir`, else `./kestrel-state`.
pub fn state_dir(flag: Option<std::path::PathBuf>, config: &Config) -> std::path::PathBuf {
    flag.or_else(|| {
        std::env::var_os("STATE_DIRECTORY")
            .map(std::path::PathBuf::from)
            // systemd may list several directories separated by ':'; the first is ours.
            .map(|p| {
                p.to_string_lossy()
                    .split(':')
                    .next()
                    .map(std::path::PathBuf::from)
                    .unwrap_or(p)
            })
    })
    .or_else(|| config.mission.state_dir.clone())
    .unwrap_or_else(|| std::path::PathBuf::from("kestrel-state"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_flag_wins_over_the_config() {
        let mut config = Config::default();
        config.mission.state_dir = Some("/var/lib/kestrel".into());
        assert_eq!(
            state_dir(Some("/tmp/x".into()), &config),
            std::path::PathBuf::from("/tmp/x")
        );
    }
}
