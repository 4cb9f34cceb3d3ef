"""USB discovery: pyusb devices paired with pyserial ttys; a clear typed message without libusb."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import usb.core
from serial.tools import list_ports

from drivers.hokuyo_scip import discovery
from drivers.hokuyo_scip.errors import ScipError, UsbBackendMissingError


def _port(device: str, vid: int | None, serial: str | None, location: str) -> SimpleNamespace:
    return SimpleNamespace(device=device, vid=vid, pid=0, serial_number=serial, product="URG-Series USB Driver",
                           location=location)


def test_missing_libusb_is_a_typed_error_and_ttys_are_still_listed(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_backend(**_: object) -> None:
        raise usb.core.NoBackendError("No backend available")

    monkeypatch.setattr(usb.core, "find", no_backend)
    monkeypatch.setattr(list_ports, "comports", lambda: [_port("/dev/ttyACM0", 0x15D1, "H1", "1-1.4:1.0"),
                                                         _port("/dev/ttyUSB0", 0x0403, "X", "1-2:1.0")])
    with pytest.raises(UsbBackendMissingError) as info:
        discovery.find_usb_devices()
    assert isinstance(info.value, ScipError) and "libusb" in str(info.value)
    result = discovery.discover()
    assert result.usb_error is not None and "libusb" in result.usb_error
    assert [d.tty for d in result.devices] == ["/dev/ttyACM0"]
    assert result.devices[0].as_dict()["vendor_id"] == "0x15d1"


def test_usb_device_is_paired_with_its_tty(monkeypatch: pytest.MonkeyPatch) -> None:
    dev = SimpleNamespace(idVendor=0x15D1, idProduct=0x0000, iSerialNumber=0, iProduct=0, bus=1, address=7,
                          port_numbers=(1, 4))
    monkeypatch.setattr(usb.core, "find", lambda **kw: [dev] if kw.get("idVendor") == 0x15D1 else [])
    monkeypatch.setattr(list_ports, "comports", lambda: [_port("/dev/ttyACM3", 0x15D1, None, "1-1.4:1.0")])
    [found] = discovery.discover().devices
    assert (found.tty, found.bus, found.address, found.location, found.source) == (
        "/dev/ttyACM3", 1, 7, "1-1.4", "usb+tty")


def test_nothing_attached(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(usb.core, "find", lambda **kw: [])
    monkeypatch.setattr(list_ports, "comports", lambda: [])
    result = discovery.discover()
    assert result.devices == () and result.usb_error is None
