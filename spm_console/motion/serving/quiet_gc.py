"""No cyclic garbage collection in the motion process while the wrist moves (:class:`QuietGc`)."""

from __future__ import annotations

import gc


class QuietGc:
    """No cyclic garbage collection in this process while the wrist moves.

    A full collection holds the GIL for as long as it takes to walk every tracked object
    (with a workspace loaded: tens of ms), stalling the loop or a bus transaction mid-way. Before
    a motion everything alive is collected once and frozen (never walked again); during it the
    collector is off (the loop allocates little, and reference counting frees it); after it,
    back to normal. This process serves no UI, so this costs nothing elsewhere.
    """

    def __init__(self) -> None:
        self.active = False

    def start(self) -> None:
        gc.collect()
        gc.freeze()
        gc.disable()
        self.active = True

    def stop(self) -> None:
        if self.active:
            gc.enable()
            gc.unfreeze()
            self.active = False

