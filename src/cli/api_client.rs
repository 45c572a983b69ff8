//! `kestrel mission run FILE --api URL`: fly a mission on a running Kestrel (the vehicle's
//! service) through its API, following it until it ends. Ctrl-C sends STOP (the vehicle holds).
//!
//! A deliberately small HTTP/1.0 client (JSON bodies, `http://` only): enough for loopback or
//! a trusted link to the companion computer, without an HTTP client in the binary.

use anyhow::{bail, Context, Result};
use serde_json::{json, Value};
use std::path::Path;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

pub struct Remote {
    host_port: String,
    token: Option<String>,
}

impl Remote {
    pub fn new(url: &str, token: Option<String>) -> Result<Self> {
        let rest = url
            .strip_prefix("http://")
            .context("--api takes http://HOST:PORT")?;
        Ok(Self {
            host_port: rest.trim_end_matches('/').to_string(),
            token,
        })
    }

    /// One request; answers the status code and the JSON body (Null when empty).
    pub async fn call(
        &self,
        method: &str,
        path: &str,
        body: Option<&Value>,
    ) -> Result<(u16, Value)> {
        let mut stream = tokio::net::TcpStream::connect(&self.host_port)
            .await
            .with_context(|| format!("cannot reach Kestrel at {}", self.host_port))?;
        let payload = body.map(Value::to_string).unwrap_or_default();
        let mut request = format!(
            "{method} {path} HTTP/1.0\r\nHost: {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n",
            self.host_port,
            payload.len()
        );
        if let Some(t) = &self.token {
            request.push_str(&format!("Authorization: Bearer {t}\r\n"));
        }
        request.push_str("\r\n");
        request.push_str(&payload);
        stream.write_all(request.as_bytes()).await?;
        let mut raw = Vec::new();
        tokio::time::timeout(Duration::from_secs(10), stream.read_to_end(&mut raw))
            .await
            .context("Kestrel did not answer in 10 s")??;
        let text = String::from_utf8_lossy(&raw);
        let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
        let status = head
            .split_whitespace()
            .nth(1)
            .and_then(|s| s.parse().ok())
            .context("not an HTTP answer")?;
        let value = if body.trim().is_empty() {
            Value::Null
        } else {
            serde_json::from_str(body).with_context(|| format!("answer is not JSON: {body}"))?
        };
        Ok((status, value))
    }
}

/// Executes `mission` on the Kestrel at `remote` and follows it; `Ok` if it succeeded.
pub async fn run(remote: Remote, mission: Value) -> Result<()> {
    let drone = mission
        .get("target")
        .and_then(Value::as_str)
        .unwrap_or("drone_0")
        .to_string();
    let (code, answer) = remote
        .call(
            "POST",
            "/api/mission_update",
            Some(&json!({"drone_id": drone, "action": 0, "mission": mission})),
        )
        .await?;
    if answer["accepted"] != true {
        let details: Vec<String> = answer["details"]
            .as_array()
            .map(|d| {
                d.iter()
                    .map(|e| {
                        format!(
                            "  {}: {}",
                            e["pointer"].as_str().unwrap_or(""),
                            e["message"].as_str().unwrap_or("")
                        )
                    })
                    .collect()
            })
            .unwrap_or_default();
        let reason = answer["reason"]
            .as_str()
            .or(answer["error"]["message"].as_str())
            .unwrap_or("refused");
        bail!("HTTP {code}: {reason}\n{}", details.join("\n"));
    }
    let id = answer["status"]["mission_id"].clone();
    println!("{drone}: mission {id} started");
    let mut last_item = Value::Null;
    loop {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {
                remote
                    .call("POST", "/api/mission_update", Some(&json!({"drone_id": drone, "mission_id": id, "action": 5})))
                    .await?;
                bail!("interrupted: mission {id} stopped, the vehicle holds");
            }
            _ = tokio::time::sleep(Duration::from_millis(500)) => {}
        }
        let (_, status) = remote.call("GET", "/api/status", None).await?;
        let Some(d) = status["drones"]
            .as_array()
            .and_then(|ds| ds.iter().find(|d| d["drone"] == drone.as_str()))
        else {
            bail!("{drone} is not in the status");
        };
        let m = &d["mission"];
        if m["mission_id"] != id {
            bail!("another mission ({}) took over", m["mission_id"]);
        }
        if m["item_index"] != last_item && !m["item_index"].is_null() {
            last_item = m["item_index"].clone();
            println!(
                "{drone}: item {last_item} {}",
                m["current_item"]["behavior"].as_str().unwrap_or("")
            );
        }
        if m["state"] == 0 {
            if let Some(e) = m["last_error"].as_str() {
                bail!("mission {id} failed: {e}");
            }
            println!("{drone}: mission {id} succeeded");
            return Ok(());
        }
    }
}

/// The API token a command presents: `--token` as given, else the text of
/// `--token-file` trimmed, else none.
pub fn token(token: Option<&str>, file: Option<&Path>) -> Result<Option<String>> {
    match (token, file) {
        (Some(t), _) => Ok(Some(t.to_string())),
        (None, Some(f)) => Ok(Some(
            std::fs::read_to_string(f)
                .with_context(|| format!("cannot read {}", f.display()))?
                .trim()
                .to_string(),
        )),
        (None, None) => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_is_the_flag_else_the_files_text_trimmed_else_none() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("token");
        std::fs::write(&file, "  s3cret\n").unwrap();
        assert_eq!(
            token(Some("flag"), Some(&file)).unwrap().as_deref(),
            Some("flag")
        );
        assert_eq!(token(None, Some(&file)).unwrap().as_deref(), Some("s3cret"));
        assert_eq!(token(None, None).unwrap(), None);
        let missing = dir.path().join("absent");
        let e = token(None, Some(&missing)).unwrap_err();
        assert!(format!("{e:#}").contains("absent"), "{e:#}");
    }
}
