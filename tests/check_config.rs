//! `kestrel check-config` refuses exactly what makes `kestrel run` refuse to start, with the
//! same message naming the file and the key, and otherwise prints a short summary. Both run as
//! the real binary, in an empty working directory, with the installed profiles looked up in a
//! temporary data directory (`KESTREL_DATA_DIR`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

struct Site {
    dir: tempfile::TempDir,
}

impl Site {
    fn new() -> Self {
        let site = Self {
            dir: tempfile::tempdir().unwrap(),
        };
        std::fs::create_dir_all(site.path("work")).unwrap();
        std::fs::create_dir_all(site.path("share/platforms")).unwrap();
        site
    }

    fn path(&self, rel: &str) -> PathBuf {
        self.dir.path().join(rel)
    }

    /// Writes `kestrel.toml`: the given sections plus log and state directories in the site.
    fn config(&self, sections: &str) -> PathBuf {
        self.config_with_dirs(sections, &self.path("log"), &self.path("state"))
    }

    /// Writes `kestrel.toml`: the given sections plus these log and state directories.
    fn config_with_dirs(&self, sections: &str, log: &Path, state: &Path) -> PathBuf {
        let path = self.path("kestrel.toml");
        let text = format!(
            "{sections}\n[drone]\nid = \"drone_0\"\nlog_dir = \"{}\"\n\n[mission]\nstate_dir = \"{}\"\n",
            log.display(),
            state.display()
        );
        std::fs::write(&path, text).unwrap();
        path
    }

    fn command(&self, args: &[&str]) -> Command {
        let mut c = Command::new(env!("CARGO_BIN_EXE_kestrel"));
        c.current_dir(self.path("work"))
            .env_remove("KESTREL_API_TOKEN")
            .env_remove("STATE_DIRECTORY")
            .env("KESTREL_DATA_DIR", self.path("share"))
            .env("RUST_BACKTRACE", "0")
            .env("RUST_LOG", "warn")
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        c
    }

    fn check(&self, config: &Path) -> Output {
        self.command(&["check-config", "--config", config.to_str().unwrap()])
            .output()
            .unwrap()
    }

    /// `kestrel run`, killed (and the test failed) if still running after 30 s.
    fn run(&self, config: &Path, extra: &[&str]) -> Output {
        let mut args = vec!["run", "--config", config.to_str().unwrap()];
        args.extend_from_slice(extra);
        let child = self.command(&args).spawn().unwrap();
        let id = child.id();
        let started = Instant::now();
        let watchdog = std::thread::spawn(move || {
            while started.elapsed() < Duration::from_secs(30) {
                std::thread::sleep(Duration::from_millis(100));
                if !Path::new(&format!("/proc/{id}")).exists() {
                    return;
                }
            }
            let _ = Command::new("kill").arg(id.to_string()).status();
        });
        let out = child.wait_with_output().unwrap();
        watchdog.join().unwrap();
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "kestrel run did not exit: {}",
            text(&out)
        );
        out
    }
}

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Both commands fail, and both say every one of `needles`.
fn both_refuse(site: &Site, config: &Path, needles: &[&str]) {
    let check = site.check(config);
    let run = site.run(config, &[]);
    for (name, out) in [("check-config", &check), ("run", &run)] {
        assert!(!out.status.success(), "{name} accepted it: {}", text(out));
        for needle in needles {
            assert!(
                text(out).contains(needle),
                "{name} does not say `{needle}`: {}",
                text(out)
            );
        }
    }
    assert!(
        !text(&run).contains("kestrel run:"),
        "run started a platform before refusing: {}",
        text(&run)
    );
}

#[test]
fn a_missing_token_file_is_refused() {
    let site = Site::new();
    let missing = site.path("api-token");
    let config = site.config(&format!(
        "[api]\nlisten = \"127.0.0.1:0\"\ntoken_file = \"{}\"\n",
        missing.display()
    ));
    both_refuse(
        &site,
        &config,
        &[
            &format!("{}: [api]", config.display()),
            &format!("cannot read the API token file {}", missing.display()),
        ],
    );
}

#[test]
fn a_public_listen_address_without_a_token_is_refused() {
    let site = Site::new();
    let config = site.config("[api]\nlisten = \"0.0.0.0:0\"\n");
    both_refuse(
        &site,
        &config,
        &["refusing to listen on 0.0.0.0:0 without an API token"],
    );
}

#[test]
fn an_unknown_platform_is_refused() {
    let site = Site::new();
    let config = site.config("[mavlink]\nplatform = \"px5\"\n");
    both_refuse(
        &site,
        &config,
        &[
            &format!("{}: mavlink.platform", config.display()),
            "no platform `px5`",
            "px4, ardupilot-copter, sim",
        ],
    );
}

#[test]
fn a_profile_path_that_does_not_resolve_is_refused_saying_where_it_looked() {
    let site = Site::new();
    let config = site.config("[mavlink]\nplatform = \"platforms/custom.toml\"\n");
    let installed = site.path("share/platforms/platforms/custom.toml");
    both_refuse(
        &site,
        &config,
        &[
            "no platform `platforms/custom.toml`",
            &site
                .path("share/platforms/custom.toml")
                .display()
                .to_string(),
            &installed.display().to_string(),
        ],
    );
}

#[test]
fn an_invalid_profile_file_is_refused() {
    let site = Site::new();
    let profile = site.path("share/platforms/broken.toml");
    std::fs::write(&profile, "platform = \"mavlink\"\nname = \"Broken\"\n").unwrap();
    let config = site.config("[mavlink]\nplatform = \"broken\"\n");
    both_refuse(&site, &config, &[&format!("profile {}", profile.display())]);
}

#[test]
fn a_log_dir_that_is_a_file_is_refused() {
    let site = Site::new();
    std::fs::write(site.path("log"), "not a directory").unwrap();
    let config = site.config("");
    both_refuse(
        &site,
        &config,
        &[
            &format!("{}: drone.log_dir", config.display()),
            "exists and is not a directory",
        ],
    );
}

#[test]
fn a_log_dir_that_cannot_be_created_is_refused() {
    let site = Site::new();
    std::fs::write(site.path("blocker"), "a file where a directory is needed").unwrap();
    let config = site.config_with_dirs("", &site.path("blocker/logs"), &site.path("state"));
    both_refuse(
        &site,
        &config,
        &[
            &format!("{}: drone.log_dir", config.display()),
            &format!("{} cannot be created", site.path("blocker/logs").display()),
            "is not a directory",
        ],
    );
}

#[test]
fn a_state_dir_that_cannot_be_created_is_refused() {
    let site = Site::new();
    // Nothing can be created in /proc, not even by root (CI runs as root).
    let config = site.config_with_dirs(
        "",
        &site.path("log"),
        Path::new("/proc/kestrel-check/state"),
    );
    both_refuse(
        &site,
        &config,
        &[
            "the state directory",
            "/proc/kestrel-check/state cannot be created in /proc",
        ],
    );
}

/// `kestrel fleet-key` makes a key in the site; its public key.
fn fleet_key(site: &Site, name: &str) -> (PathBuf, String) {
    let path = site.path(name);
    let out = site
        .command(&["fleet-key", path.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let public = text(&out)
        .lines()
        .find_map(|l| l.strip_prefix("public key: "))
        .expect("the public key printed")
        .to_string();
    (path, public)
}

/// A `[fleet]` section that `run` would open: node `kestrel-a` with its key and a roster of
/// two, and `extra` lines.
fn fleet_section(site: &Site, extra: &str) -> String {
    let (key, public) = fleet_key(site, "fleet.key");
    let (_, other) = fleet_key(site, "other.key");
    format!(
        "[fleet]\nenabled = true\nname = \"farm\"\nnode = \"kestrel-a\"\n\
         listen = [\"tcp/127.0.0.1:0\"]\nkey_file = \"{}\"\n{extra}\n\
         [fleet.roster.kestrel-a]\nkeys = [\"{public}\"]\ndrones = [\"drone_0\"]\n\
         [fleet.roster.kestrel-b]\nkeys = [\"{other}\"]\ndrones = [\"drone_1\"]\n",
        key.display()
    )
}

/// A `[fleet]` section that `run` would open, with this credentials file.
fn fleet_with_credentials(site: &Site, credentials: &Path) -> PathBuf {
    let extra = format!("credentials_file = \"{}\"", credentials.display());
    site.config(&fleet_section(site, &extra))
}

/// Issue 29: every node signs with its own key, listed in the roster. A config of before (one
/// shared credentials file, no key) is refused saying what to do.
#[test]
fn a_fleet_without_a_key_and_roster_is_refused_saying_how_to_make_them() {
    let site = Site::new();
    let config =
        site.config("[fleet]\nenabled = true\nname = \"farm\"\nlisten = [\"tcp/127.0.0.1:0\"]\n");
    both_refuse(&site, &config, &["fleet.key_file", "kestrel fleet-key"]);
}

#[test]
fn a_key_that_is_not_this_nodes_in_the_roster_is_refused() {
    let site = Site::new();
    let section = fleet_section(&site, "");
    let (stranger, _) = fleet_key(&site, "stranger.key");
    let own = site.path("fleet.key");
    let config = site.config(&section.replace(own.to_str().unwrap(), stranger.to_str().unwrap()));
    both_refuse(
        &site,
        &config,
        &["is not among [fleet.roster.kestrel-a] keys"],
    );
}

#[test]
fn a_fleet_with_its_key_in_the_roster_is_checked_ok() {
    let site = Site::new();
    let config = site.config(&fleet_section(&site, ""));
    let out = site.check(&config);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("fleet      `farm` as node `kestrel-a`, 2 members in the roster"),
        "{}",
        text(&out)
    );
    assert!(
        !text(&out).contains("readable by other users"),
        "{}",
        text(&out)
    );
}

#[test]
fn a_missing_fleet_credentials_file_is_refused() {
    let site = Site::new();
    let missing = site.path("fleet-credentials");
    let config = fleet_with_credentials(&site, &missing);
    both_refuse(
        &site,
        &config,
        &[&format!(
            "{}: fleet.credentials_file {}: No such file",
            config.display(),
            missing.display()
        )],
    );
}

#[test]
fn a_malformed_fleet_credentials_file_is_refused_naming_the_line() {
    let site = Site::new();
    let credentials = site.path("fleet-credentials");
    std::fs::write(&credentials, "kestrel-a:s3cret\n\nkestrel-b s3cret\n").unwrap();
    let config = fleet_with_credentials(&site, &credentials);
    both_refuse(
        &site,
        &config,
        &[&format!(
            "fleet.credentials_file {}: line 3: not `user:password`",
            credentials.display()
        )],
    );
}

/// `KESTREL_API_TOKEN` is used before `[api] token_file`, so a missing file starts; the day the
/// service runs without the variable it would not: check-config says so now.
#[test]
fn a_token_file_hidden_by_the_environment_is_warned_about() {
    let site = Site::new();
    let missing = site.path("api-token");
    let config = site.config(&format!(
        "[api]\nlisten = \"127.0.0.1:0\"\ntoken_file = \"{}\"\n",
        missing.display()
    ));
    let out = site
        .command(&["check-config", "--config", config.to_str().unwrap()])
        .env("KESTREL_API_TOKEN", "from-the-environment")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("  token      yes\n"), "{stdout}");
    assert!(
        stdout.contains(&format!(
            "  warning    api.token_file {}: ",
            missing.display()
        )) && stdout.contains("KESTREL_API_TOKEN is used instead"),
        "{stdout}"
    );
    // With the file there, nothing to warn about.
    std::fs::write(&missing, "secret\n").unwrap();
    let out = site
        .command(&["check-config", "--config", config.to_str().unwrap()])
        .env("KESTREL_API_TOKEN", "from-the-environment")
        .output()
        .unwrap();
    assert!(
        !String::from_utf8_lossy(&out.stdout).contains("warning"),
        "{}",
        text(&out)
    );
}

#[test]
fn an_installed_profile_is_found_by_relative_path_and_summarised() {
    let site = Site::new();
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(
        repo.join("platforms/ardupilot-copter.toml"),
        site.path("share/platforms/ardupilot-copter.toml"),
    )
    .unwrap();
    std::fs::write(site.path("token"), "secret\n").unwrap();
    let config = site.config(&format!(
        "[mavlink]\nplatform = \"platforms/ardupilot-copter.toml\"\nconnection = \"serial:/dev/ttyACM0:115200\"\n\n[api]\nlisten = \"0.0.0.0:8080\"\ntoken_file = \"{}\"\n",
        site.path("token").display()
    ));
    let out = site.check(&config);
    assert!(out.status.success(), "{}", text(&out));
    let expected = format!(
        "OK: {}\n  drone id   drone_0\n  platform   ArduPilot Copter ({})\n  mavlink    serial:/dev/ttyACM0:115200\n  api        0.0.0.0:8080\n  token      yes\n  log dir    {}\n  state dir  {}\n",
        config.display(),
        site.path("share/platforms/ardupilot-copter.toml").display(),
        site.path("log").display(),
        site.path("state").display()
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout), expected);
}

/// The shipped config (systemd/kestrel.toml) names no platform: the built-in PX4 profile, with
/// no profile file anywhere. `run` starts with it (issue 12: it used to look for
/// `platforms/px4.toml` in the service's working directory and exit).
#[test]
fn the_shipped_config_starts_with_the_built_in_px4_profile() {
    let site = Site::new();
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::write(site.path("api-token"), "secret\n").unwrap();
    let shipped = std::fs::read_to_string(repo.join("systemd/kestrel.toml")).unwrap();
    let rewritten = shipped
        .replace("/etc/kestrel/", &format!("{}/", site.dir.path().display()))
        .replace("/var/log/kestrel", &site.path("log").display().to_string())
        .replace(
            "/var/lib/kestrel",
            &site.path("state").display().to_string(),
        );
    let config = site.path("shipped.toml");
    std::fs::write(&config, rewritten).unwrap();
    let out = site.check(&config);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("platform   PX4 (built-in px4)"),
        "{}",
        text(&out)
    );
    let udp = support::free_udp_port();
    let run = site.run(
        &config,
        &[
            "--connection",
            &format!("udpin:127.0.0.1:{udp}"),
            "--no-api",
            "--max-time-s",
            "1",
        ],
    );
    assert!(run.status.success(), "{}", text(&run));
    assert!(
        text(&run).contains(&format!(
            "kestrel run: PX4 over udpin:127.0.0.1:{udp} (profile built-in px4)"
        )),
        "{}",
        text(&run)
    );
}

/// Two vehicles of a `[[vehicle]]` list, one of an installed profile file, the other with
/// `[mavlink] platform`.
fn fleet_sections(site: &Site, second_connection: &str) -> String {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::copy(
        repo.join("platforms/ardupilot-copter.toml"),
        site.path("share/platforms/ardupilot-copter.toml"),
    )
    .unwrap();
    format!(
        "[mavlink]\nplatform = \"px4\"\n\n[[vehicle]]\nid = \"scout\"\nconnection = \"udpin:0.0.0.0:14540\"\ntarget_system = 1\n\n[[vehicle]]\nid = \"lifter\"\nplatform = \"platforms/ardupilot-copter.toml\"\nconnection = \"{second_connection}\"\ntarget_system = 2\norigin_enu_m = [3.0, -1.5, 0.0]\nforward = [\"udpout:127.0.0.1:14550\"]\n"
    )
}

#[test]
fn a_vehicle_list_is_summarised_one_line_per_vehicle() {
    let site = Site::new();
    let config = site.config(&fleet_sections(&site, "serial:/dev/ttyACM0:115200"));
    let out = site.check(&config);
    assert!(out.status.success(), "{}", text(&out));
    let expected = format!(
        "OK: {}\n  vehicles   2\n  scout: PX4 (built-in px4) over udpin:0.0.0.0:14540, system id 1, origin [0, 0, 0] m\n  lifter: ArduPilot Copter ({}) over serial:/dev/ttyACM0:115200, system id 2, origin [3, -1.5, 0] m, forward udpout:127.0.0.1:14550\n  api        127.0.0.1:8080\n  token      no\n  log dir    {}\n  state dir  {}\n",
        config.display(),
        site.path("share/platforms/ardupilot-copter.toml").display(),
        site.path("log").display(),
        site.path("state").display()
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout), expected);
}

#[test]
fn vehicles_behind_one_connection_need_their_own_system_ids_and_one_forward_list() {
    let site = Site::new();
    let shared = fleet_sections(&site, "udpin:127.0.0.1:14540");
    // The forward belongs to the connection: every vehicle on it lists the same.
    let config = site.config(&shared);
    both_refuse(
        &site,
        &config,
        &[
            &format!("{}", config.display()),
            "vehicle[1].forward",
            "must list the same `forward`",
        ],
    );
    let shared = shared.replace("forward = [\"udpout:127.0.0.1:14550\"]\n", "");
    // Told apart by system id: each must name its own.
    let config = site.config(&shared.replace("target_system = 2\n", ""));
    both_refuse(&site, &config, &["vehicle[1].connection", "target_system"]);
    let config = site.config(&shared.replace("target_system = 2\n", "target_system = 1\n"));
    both_refuse(&site, &config, &["vehicle[1].target_system", "vehicle[0]"]);
    let config = site.config(&shared);
    let out = site.check(&config);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("lifter: ArduPilot Copter")
            && text(&out).contains("over udpin:127.0.0.1:14540, system id 2"),
        "{}",
        text(&out)
    );
}

#[test]
fn a_repeated_vehicle_id_is_refused() {
    let site = Site::new();
    let sections = fleet_sections(&site, "udpin:0.0.0.0:14541").replace("\"lifter\"", "\"scout\"");
    let config = site.config(&sections);
    both_refuse(
        &site,
        &config,
        &["vehicle[1].id", "`scout` is also vehicle[0]'s id"],
    );
}

/// `--connection` would say which vehicle's? `run` refuses it with a list.
#[test]
fn run_refuses_a_connection_flag_with_a_vehicle_list() {
    let site = Site::new();
    let config = site.config(&fleet_sections(&site, "udpin:0.0.0.0:14541"));
    let out = site.run(
        &config,
        &["--connection", "udpin:127.0.0.1:14600", "--no-api"],
    );
    assert!(!out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("--connection") && text(&out).contains("[[vehicle]] list"),
        "{}",
        text(&out)
    );
    assert!(!text(&out).contains("kestrel run:"), "{}", text(&out));
}

/// `--virtual-world`: a missing or invalid world file stops both commands before anything is
/// opened, naming the file (and the field); a good one is summarised with each vehicle's sensor.
#[test]
fn a_virtual_world_is_checked_before_anything_flies() {
    let site = Site::new();
    let config = site.config(&fleet_sections(&site, "udpin:0.0.0.0:14541"));
    let missing = site.path("nowhere.json");
    let bad = site.path("bad.json");
    std::fs::write(
        &bad,
        r#"{"bounds_m": {"x": [-5, 5], "y": [-5, 5]}, "boxes": [{"center_xy_m": [0, 0], "size_xy_m": [1, -2]}]}"#,
    )
    .unwrap();
    for (world, needle) in [
        (&missing, "cannot read world file"),
        (&bad, "boxes[0].size_xy_m"),
    ] {
        let flag = ["--virtual-world", world.to_str().unwrap()];
        let mut check = vec!["check-config", "--config", config.to_str().unwrap()];
        check.extend_from_slice(&flag);
        let check = site.command(&check).output().unwrap();
        let run = site.run(&config, &[&flag[..], &["--no-api"]].concat());
        for (name, out) in [("check-config", &check), ("run", &run)] {
            assert!(!out.status.success(), "{name} accepted it: {}", text(out));
            for n in ["--virtual-world", &world.display().to_string(), needle] {
                assert!(
                    text(out).contains(n),
                    "{name} does not say `{n}`: {}",
                    text(out)
                );
            }
        }
        assert!(!text(&run).contains("kestrel run:"), "{}", text(&run));
    }

    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let room = repo.join("sitl/worlds/room10_fleet.json");
    let lidar = fleet_sections(&site, "udpin:0.0.0.0:14541").replace(
        "origin_enu_m = [3.0, -1.5, 0.0]\n",
        "origin_enu_m = [3.0, -1.5, 0.0]\nsensor = { kind = \"lidar360\", beams = 90 }\n",
    );
    let config = site.config(&lidar);
    let out = site
        .command(&[
            "check-config",
            "--config",
            config.to_str().unwrap(),
            "--virtual-world",
            room.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let expected = format!(
        "  virtual world  {} (9 obstacles)\n  scout: sensor multiranger, 4 m, 20 Hz\n  lifter: sensor lidar360, 90 beams, 10 m, 10 Hz\n",
        room.display()
    );
    assert!(text(&out).ends_with(&expected), "{}", text(&out));
}
