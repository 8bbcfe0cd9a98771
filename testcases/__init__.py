"""Scene files (TOML), one per test case; a package so that they ship with the install."""
