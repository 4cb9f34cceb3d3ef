"""Errors of the application layer (drivers have their own under ``drivers.errors``)."""

from __future__ import annotations


class AppError(Exception):
    """An error the CLI reports as one line and a non-zero exit."""


class ConfigError(AppError, ValueError):
    """A bad configuration value; the message names the key."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(f"config key '{key}': {message}")
        self.key = key


class LogFormatError(AppError):
    """A field log that cannot be read (truncated, wrong schema, not MCAP)."""
