"""Service calls that survive a reply lost to discovery.

rmw_fastrtps sends a service's reply only once the client's reply reader is matched
with the server's reply writer, and waits 100 ms for that; after that it drops the
reply with "client will not receive response". This is Fast DDS's discovery running
one way faster than the other, not a fault of the server. It happens while a node
is still being discovered: right after it starts, and on a busy machine.
``service_is_ready()`` on the client only says that the request path is matched.

A query (``get_parameters``) is idempotent, so it is sent again while no reply has
come; the first reply to any of the copies is the answer. A request that acts (a
Trigger that starts a motion) must not be sent twice and is not handled here.
"""
from __future__ import annotations

import time
from typing import Callable

from rclpy.task import Future


def query(client, request, spin_once: Callable[[float], None], timeout_s: float,
          resend_s: float = 2.0):
    """The reply to the idempotent ``request``, sent again every ``resend_s`` [s] without a
    reply; None when no reply came within ``timeout_s`` [s].  ``spin_once(seconds)`` spins the
    executor that holds the client's node."""
    end = time.monotonic() + timeout_s
    futures: list[Future] = []
    sent = -float("inf")
    while True:
        for future in futures:
            if future.done():
                for other in futures:
                    if other is not future:
                        client.remove_pending_request(other)
                return future.result()
        now = time.monotonic()
        if now > end:
            for future in futures:
                client.remove_pending_request(future)
            return None
        if now - sent >= resend_s:
            futures.append(client.call_async(request))
            sent = now
        spin_once(0.05)
