"""MAVLink 2 message signing: the key, and a parser that requires it.

The key is 32 bytes shared by the ground station and the vehicles. A key file
holding exactly 32 bytes is used as it is; anything else is read as a passphrase
and hashed with SHA-256, as MAVProxy's `signing setup PASSPHRASE` does, so the
same passphrase gives the same key in both tools.

With a key, everything we send is signed, and packets arriving unsigned or with a
wrong signature fail to parse and are dropped (counted, so an error can say why
no vehicle was heard).
"""

import hashlib
import time
from pathlib import Path

from common.errors import InputError

KEY_BYTES = 32
EPOCH_2015 = 1420070400        # signing timestamps count 10 us since 2015-01-01 UTC


def key_from_passphrase(passphrase: str) -> bytes:
    """MAVProxy's passphrase -> key: SHA-256 of the text."""
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


def load_key(path) -> bytes:
    """A 32-byte key file, or a passphrase file (one line) hashed as MAVProxy does."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(path, f"cannot read signing key: {exc.strerror or exc}") from exc
    if len(data) == KEY_BYTES:
        return data
    try:
        text = data.decode("utf-8").strip()
    except UnicodeDecodeError:
        raise InputError(path, f"signing key must be {KEY_BYTES} bytes or a text passphrase, "
                               f"got {len(data)} binary bytes") from None
    if not text:
        raise InputError(path, "signing key file is empty")
    return key_from_passphrase(text)


def timestamp_now() -> int:
    """The signing timestamp for now, in 10 us units since 2015."""
    return int(max(time.time() - EPOCH_2015, 0) * 100_000)


def apply(mav, key: bytes | None, link_id: int = 0) -> None:
    """Make a pymavlink MAVLink object sign what it packs and reject unsigned input.

    Rejection happens in pymavlink's parser: with a secret key and an
    `allow_unsigned_callback` that says no, a packet without a valid signature
    raises "Invalid signature" (BAD_DATA with robust parsing)."""
    if key is None:
        return
    if len(key) != KEY_BYTES:
        raise ValueError(f"a MAVLink signing key is {KEY_BYTES} bytes, got {len(key)}")
    mav.signing.secret_key = bytes(key)
    mav.signing.sign_outgoing = True
    mav.signing.link_id = link_id
    mav.signing.timestamp = timestamp_now()
    mav.signing.allow_unsigned_callback = _refuse_unsigned


def _refuse_unsigned(_mav, _msgid) -> bool:
    return False


def is_signature_reject(bad_data) -> bool:
    """Whether a BAD_DATA message is a packet dropped for its signature."""
    return "signature" in str(getattr(bad_data, "reason", "")).lower()


def install_key(vehicle, key: bytes) -> None:
    """Send SETUP_SIGNING to a vehicle (over a link you trust, e.g. USB): ArduPilot
    stores the key and from then on requires signed messages on its MAVLink ports."""
    vehicle.send("SETUP_SIGNING", secret_key=list(key), initial_timestamp=timestamp_now())
