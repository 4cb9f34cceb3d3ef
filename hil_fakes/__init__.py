"""Byte-level fake devices (UTM-30LX, Pioneer 3-DX, SNC-RZ50) and the simulated world feeding them.

Import rules: standard library, numpy and OpenCV only; never ``drivers`` (a fake is an independent
model of its device, written from the fact sheets, so a codec bug cannot hide behind a matching fake
bug), never ``vipsm`` or ``app``.
"""
