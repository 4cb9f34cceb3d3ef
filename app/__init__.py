"""The vipsm-robot application: CLI, config, control loop, field log, status server."""
