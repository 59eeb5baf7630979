"""The ``rosbags`` type store: ROS 2 Jazzy types plus the project's ``tire_estimation_msgs``.

The custom message definitions are read from the ``.msg`` files of ``tire_estimation_msgs``:
first an installed ``share/tire_estimation_msgs/msg`` under any prefix of ``AMENT_PREFIX_PATH``,
then the source tree next to this package.

:func:`bag_typestore` builds a store for reading from the message definitions a bag carries
(MCAP ``ros2msg`` schemas): about 20 ms against about 120 ms for the full Jazzy store, whose
import is most of the cold-start cost of reading a bag.
"""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg
from rosbags.typesys import get_typestore as _rosbags_typestore
from rosbags.typesys.store import Typestore

from tire_estimation.errors import BagError

MSG_PACKAGE = "tire_estimation_msgs"


def find_msg_dir() -> Path:
    """Directory holding ``tire_estimation_msgs``'s ``.msg`` files.

    Raises:
        BagError: neither an installed package nor the source tree has the definitions.
    """
    searched: list[str] = []
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if not prefix:
            continue
        candidate = Path(prefix) / "share" / MSG_PACKAGE / "msg"
        searched.append(str(candidate))
        if candidate.is_dir() and any(candidate.glob("*.msg")):
            return candidate
    candidate = Path(__file__).resolve().parents[3] / MSG_PACKAGE / "msg"
    searched.append(str(candidate))
    if candidate.is_dir() and any(candidate.glob("*.msg")):
        return candidate
    raise BagError(f"cannot find {MSG_PACKAGE} .msg files; searched: {', '.join(searched)}")


def custom_types(msg_dir: Path) -> dict[str, object]:
    """Parse every ``.msg`` file of ``msg_dir`` into a ``rosbags`` types dict.

    All definitions are parsed before any is registered, so a message that uses another one of
    the package (``DeflationStatus`` uses ``WheelDeflation``) is registered together with it.
    """
    types: dict[str, object] = {}
    for path in sorted(msg_dir.glob("*.msg")):
        name = f"{MSG_PACKAGE}/msg/{path.stem}"
        try:
            types.update(get_types_from_msg(path.read_text(), name))
        except Exception as exc:  # rosbags raises several parser error types
            raise BagError(f"cannot parse message definition {path}: {exc}") from exc
    return types


@cache
def get_typestore() -> Typestore:
    """The shared type store (ROS 2 Jazzy + ``tire_estimation_msgs``); built once per process."""
    store = _rosbags_typestore(Stores.ROS2_JAZZY)
    types = custom_types(find_msg_dir())
    store.register(types)  # type: ignore[arg-type]
    missing = [name for name in types if name not in store.types]
    if missing:
        raise BagError(f"type store did not register {missing}")
    for name in types:  # fail here, not in the writer, when a dependency is missing
        store.hash_rihs01(name)
    return store


@cache
def bag_typestore(schemas: tuple[tuple[str, str, str], ...]) -> Typestore:
    """A store with the types of ``schemas`` (message type, schema encoding, schema text) as a
    bag's MCAP Schema records give them; the shared :func:`get_typestore` when any of them is
    not a parseable ``ros2msg`` definition (sqlite3 bags, other encodings, missing records).
    """
    if not schemas or any(enc != "ros2msg" or not text for _, enc, text in schemas):
        return get_typestore()
    store = _rosbags_typestore(Stores.EMPTY)
    try:
        for name, _, text in schemas:
            store.register(get_types_from_msg(text, name))  # type: ignore[arg-type]
        for name, _, _ in schemas:  # every type and its dependencies are defined
            store.hash_rihs01(name)
    except Exception:  # rosbags raises several parser and type-system error types
        return get_typestore()
    return store
