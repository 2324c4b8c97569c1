//! How a run's link across hosts is protected (`--tls DIR` or `--insecure`),
//! shared by `etp run --listen` and `etp sensor-host`: the rule (a `tls/`
//! endpoint with a key folder, or plain `tcp/` only when asked for) is
//! `etp_runtime::link_keys::resolve`, checked here before any process starts
//! and again by the bridge.

use anyhow::Result;
use etp_runtime::link_keys;
use std::path::PathBuf;

#[derive(Debug, Clone, Default, clap::Args)]
pub struct LinkArgs {
    /// Key folder of `etp certs init DIR`: the link is TLS, both ends
    /// authenticated by the folder's CA (endpoints `tls/ADDR:PORT`). The default.
    #[arg(long, value_name = "DIR", conflicts_with = "insecure")]
    pub tls: Option<PathBuf>,
    /// Plain TCP (`tcp/ADDR:PORT`): no authentication, no encryption.
    /// For isolated test networks only. Also lets `etp run --live` serve
    /// its (plain WebSocket) view on an address other than loopback.
    #[arg(long)]
    pub insecure: bool,
}

impl LinkArgs {
    /// The bridge's arguments for `endpoint` as host `name` of the key
    /// folder, checked (refusal names the option); `--insecure` is warned.
    pub fn bridge_args(&self, endpoint: &str, name: &str) -> Result<Vec<String>> {
        link_keys::resolve(endpoint, self.tls.as_deref(), name, self.insecure)?;
        if self.insecure {
            eprintln!(
                "etp: warning: --insecure: the link at {endpoint} is plain TCP, neither \
                 authenticated nor encrypted (isolated test networks only)"
            );
            return Ok(vec!["--insecure".into()]);
        }
        let dir = self.tls.as_ref().map(|d| {
            std::path::absolute(d)
                .unwrap_or_else(|_| d.clone())
                .display()
                .to_string()
        });
        Ok(match dir {
            Some(d) => vec!["--tls".into(), d],
            None => Vec::new(),
        })
    }
}
