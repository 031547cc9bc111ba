"""Messages between the training process and the SAC learner process (semdp/README.md, "SAC
learner process"): pickled with the standard pickler over a socket :class:`Connection`."""

from __future__ import annotations

import pickle
from multiprocessing.connection import Connection
from typing import Any


def send_message(conn: Connection, message: Any) -> None:
    """Send with the standard pickler: tensors are copied, not moved to shared memory as
    ``multiprocessing``'s pickler does once torch is imported (that needs a parent's authkey)."""
    conn.send_bytes(pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL))


def receive_message(conn: Connection) -> Any:
    """Receive what :func:`send_message` sent."""
    return pickle.loads(conn.recv_bytes())
