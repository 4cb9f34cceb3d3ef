"""Whether a process still runs: the owner of a temporary file or folder left behind (a killed
``sim``'s folder, a killed figure writer's partial file) is cleaned up only once it is gone."""

from __future__ import annotations

import os


def process_alive(pid: int) -> bool:
    """True while ``pid`` runs (also when it belongs to another user, who may not be signalled)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
