"""``python -m app`` runs the ``vipsm-robot`` CLI."""

from app.cli import main

raise SystemExit(main())
