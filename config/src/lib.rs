//! Every setting, loaded from TOML and validated into types that cannot hold invalid values.
