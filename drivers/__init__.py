"""Device drivers: one package per device, each a sans-I/O codec plus a thin client.

Import rules (enforced by ``tests/test_import_rules.py``): drivers may import the standard
library, pyserial, pyusb and numpy, never ``vipsm``, ``app`` or ``hil_fakes``.
"""
