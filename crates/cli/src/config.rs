//! `--config DIR`: where the local configuration is (docs/configuration.md).

use std::path::PathBuf;

use cetratus_node::config::LocalConfig;

/// Where the configuration directory is.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ConfigArgs {
    /// The local configuration directory (trusted keys, operator keys, config.toml).
    #[arg(long = "config")]
    pub config: Option<PathBuf>,
}

impl ConfigArgs {
    /// Loads the configuration.
    pub fn load(&self) -> anyhow::Result<LocalConfig> {
        Ok(LocalConfig::load(self.config.as_deref())?)
    }
}
