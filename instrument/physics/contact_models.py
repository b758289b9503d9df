"""The normal-contact models and the one factory that makes them.

``"cutoff"``: the paper's hereditary model with the no-adhesion cutoff
(:class:`gelrig.instrument.physics.contact.NormalContact`, physics.md 1); ``"mdr"``: the method of
dimensionality reduction with viscoelastic elements
(:class:`gelrig.instrument.physics.mdr.MdrContact`,
physics.md 1b, docs/decisions/0150). Both meet :class:`ContactModel`, the streaming contract
the simulators and the model fit use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal, Protocol

from gelrig.instrument.core.errors import ConfigError

if TYPE_CHECKING:  # the models are imported when one is made: the names here stay light
    from numpy.typing import ArrayLike

    from gelrig.instrument.physics.contact import FloatArray, Material

Unloading = Literal["cutoff", "mdr"]
UNLOADING_MODELS: tuple[str, ...] = ("cutoff", "mdr")


class ContactModel(Protocol):
    """The streaming contract every normal-contact model meets (simulators, the model fit)."""

    t_last: float | None

    def step(self, t: float, delta: float) -> float: ...

    def block(self, t: ArrayLike, delta: ArrayLike) -> FloatArray: ...

    def block_uniform(self, delta: ArrayLike, dt: float) -> FloatArray: ...

    def reset(self) -> None: ...

    def snapshot(self) -> object: ...

    def restore(self, state: object) -> None: ...


def make_contact(
    material: Material,
    radius: float,
    unloading: Unloading | str = "cutoff",
    *,
    carry_history: bool = False,
) -> ContactModel:
    """The one place a normal contact is made (simulators, the model, ``gelrig model``).

    ``unloading``: ``"cutoff"`` is the paper's hereditary model with the no-adhesion cutoff;
    ``"mdr"`` is the method of dimensionality reduction with viscoelastic elements
    (physics.md 1b, ``instrument/physics/mdr.py``, docs/decisions/0150).
    ``carry_history`` keeps the hereditary state across separations (a sensitivity option,
    docs/decisions/0140); the default starts each contact fresh.
    """
    if unloading == "cutoff":
        from gelrig.instrument.physics.contact import NormalContact

        return NormalContact(material, radius, carry_history=carry_history)
    if unloading == "mdr":
        from gelrig.instrument.physics.mdr import MdrContact

        return MdrContact(material, radius, carry_history=carry_history)
    raise ConfigError("unloading", unloading, f"allowed: {', '.join(UNLOADING_MODELS)}")
