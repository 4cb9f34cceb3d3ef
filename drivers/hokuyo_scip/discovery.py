"""Find attached Hokuyo URG-family scanners (USB vendor 0x15d1) and their tty.

Two sources, merged:

* pyusb (needs a libusb backend): every device with the vendor id, with its serial number (when
  the system lets us read string descriptors) and bus/address;
* pyserial's ``list_ports`` (sysfs, no libusb needed): CDC-ACM ttys with the vendor id, with their
  serial number and device path.

A USB device and a tty are paired by serial number, else by bus location. Without libusb,
:func:`find_usb_devices` raises :class:`UsbBackendMissingError` with how to install it, and
:func:`discover` reports that in ``usb_error`` while still listing the ttys.

The vendor id is from the fact sheet (seen on a UTX-10LN; assumed the same for the UTM-30LX [?]),
so it is a parameter.
"""

from __future__ import annotations

from dataclasses import dataclass

from .errors import UsbBackendMissingError

HOKUYO_VENDOR_ID = 0x15D1

LIBUSB_HINT = (
    "pyusb found no libusb backend; install libusb 1.0 (Debian/Ubuntu: apt-get install libusb-1.0-0) "
    "to list scanners by USB id; ttys are still listed from sysfs"
)


@dataclass(frozen=True)
class ScannerDevice:
    vendor_id: int
    product_id: int
    serial_number: str | None
    tty: str | None  # /dev/ttyACM0 etc., when the CDC-ACM driver bound it
    product: str | None = None
    bus: int | None = None
    address: int | None = None
    location: str | None = None
    source: str = "usb"  # "usb" (pyusb), "tty" (pyserial list_ports), or "usb+tty"

    def as_dict(self) -> dict[str, object]:
        return {
            "device": "scanner",
            "vendor_id": f"0x{self.vendor_id:04x}",
            "product_id": f"0x{self.product_id:04x}",
            "serial_number": self.serial_number,
            "tty": self.tty,
            "product": self.product,
            "bus": self.bus,
            "address": self.address,
            "location": self.location,
            "source": self.source,
        }


@dataclass(frozen=True)
class DiscoveryResult:
    devices: tuple[ScannerDevice, ...]
    usb_error: str | None = None  # why the pyusb half could not run (e.g. no libusb)


def find_usb_devices(vendor_id: int = HOKUYO_VENDOR_ID) -> list[ScannerDevice]:
    """Devices with ``vendor_id`` through pyusb; raises :class:`UsbBackendMissingError` without libusb."""
    try:
        import usb.core
        import usb.util
    except ImportError as exc:  # pragma: no cover - pyusb is a declared dependency
        raise UsbBackendMissingError(f"pyusb is not installed: {exc}") from exc
    try:
        found = list(usb.core.find(find_all=True, idVendor=vendor_id) or [])
    except usb.core.NoBackendError as exc:
        raise UsbBackendMissingError(LIBUSB_HINT) from exc
    devices = []
    for dev in found:
        serial_number = _usb_string(dev, getattr(dev, "iSerialNumber", 0))
        product = _usb_string(dev, getattr(dev, "iProduct", 0))
        bus = getattr(dev, "bus", None)
        ports = getattr(dev, "port_numbers", None)
        location = f"{bus}-{'.'.join(str(p) for p in ports)}" if bus is not None and ports else None
        devices.append(
            ScannerDevice(
                vendor_id=int(dev.idVendor),
                product_id=int(dev.idProduct),
                serial_number=serial_number,
                tty=None,
                product=product,
                bus=bus,
                address=getattr(dev, "address", None),
                location=location,
                source="usb",
            )
        )
    return devices


def _usb_string(dev: object, index: int) -> str | None:
    """A string descriptor, or None when it is absent or we may not read it (permissions)."""
    if not index:
        return None
    try:
        import usb.util

        return str(usb.util.get_string(dev, index))
    except Exception:  # noqa: BLE001 - pyusb raises USBError/ValueError/NotImplementedError here
        return None


def find_ttys(vendor_id: int = HOKUYO_VENDOR_ID) -> list[ScannerDevice]:
    """Serial ports whose USB vendor id is ``vendor_id`` (pyserial's list_ports; no libusb needed)."""
    from serial.tools import list_ports

    out = []
    for info in list_ports.comports():
        if info.vid != vendor_id:
            continue
        out.append(
            ScannerDevice(
                vendor_id=int(info.vid),
                product_id=int(info.pid or 0),
                serial_number=info.serial_number,
                tty=info.device,
                product=info.product,
                location=_bus_location(info.location),
                source="tty",
            )
        )
    return out


def _bus_location(location: str | None) -> str | None:
    """pyserial's location ``1-1.4:1.0`` -> ``1-1.4`` (the interface suffix dropped)."""
    if not location:
        return None
    return location.split(":")[0]


def discover(vendor_id: int = HOKUYO_VENDOR_ID) -> DiscoveryResult:
    """USB devices paired with their ttys; ttys alone (with ``usb_error``) where libusb is missing."""
    ttys = find_ttys(vendor_id)
    try:
        usb_devices = find_usb_devices(vendor_id)
    except UsbBackendMissingError as exc:
        return DiscoveryResult(tuple(ttys), usb_error=str(exc))
    merged: list[ScannerDevice] = []
    unpaired = list(ttys)
    for dev in usb_devices:
        match = next(
            (
                t
                for t in unpaired
                if (dev.serial_number and t.serial_number == dev.serial_number)
                or (dev.location and t.location == dev.location)
            ),
            None,
        )
        if match is not None:
            unpaired.remove(match)
            merged.append(
                ScannerDevice(
                    vendor_id=dev.vendor_id,
                    product_id=dev.product_id,
                    serial_number=dev.serial_number or match.serial_number,
                    tty=match.tty,
                    product=dev.product or match.product,
                    bus=dev.bus,
                    address=dev.address,
                    location=dev.location or match.location,
                    source="usb+tty",
                )
            )
        else:
            merged.append(dev)
    merged.extend(unpaired)
    return DiscoveryResult(tuple(merged))
