"""The oil column's analytic frequency from a series' table description.

The actuator's oil is a spring between the valve and the piston: compressing a chamber of
volume V by a piston of area A through a stroke x raises its pressure by beta*A*x/V
(beta the oil's bulk modulus), so the chamber pushes back with stiffness beta*A^2/V. Against
the moving mass M the column rings at

    f_oil = (1/2pi)*sqrt(k_oil/M),   k_oil = chambers*beta*A^2/V.

chambers=2 (the default, the reference study's 2*beta form): a double-acting actuator has
two chambers, one on each side of the piston, and table.oil.oil_volume_m3 is the volume V
of *each* of them. Moving the piston compresses one chamber and expands the other; both
push it back, each with beta*A^2/V, so k_oil = 2*beta*A^2/V. (They act on the one piston,
as springs of the same displacement, so their stiffnesses add.) This is how the study and
the twin (TableTruth.oil_volume, "each of the two chambers") state V.

chambers=4: the same actuator when V is the *total* oil volume, split into two halves of
V/2 with the piston centred. Each half then gives beta*A^2/(V/2) = 2*beta*A^2/V, and
k_oil = 4*beta*A^2/V. Use it when the volume you have is the whole actuator's (cylinder bore
times full stroke, plus the lines). Both forms hold for the centred piston: off centre one
chamber is smaller, k_oil = beta*A^2*(1/V1 + 1/V2) grows, and the frequency is higher, so
the centred value is the lowest the column reaches.

The moving mass is the deck plus any payload. table.deck_mass_kg is the deck alone; the
mass that rides on the oil column also holds the piston, rod and fixtures, so a table's
identified Me is usually somewhat larger (the twin's preset: 12 t deck, Me = 13.2 t). Give
moving_mass_kg (the empty table's moving mass, e.g. an identified Me) to use it instead, or
put "moving_mass_kg" in the series' table description, which is read before deck_mass_kg.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, Mapping

from bayes_sst.physics import oil_column_frequency

CHAMBER_FORMS = (2, 4)


def _number(table: Mapping[str, Any], *keys: str) -> float | None:
    value: Any = table
    for key in keys:
        if not isinstance(value, Mapping) or key not in value:
            return None
        value = value[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    value = float(value)
    return value if math.isfinite(value) and value > 0.0 else None


def empty_moving_mass(table: Mapping[str, Any] | None, moving_mass_kg: float | None = None) -> float | None:
    """The empty table's moving mass, kg: moving_mass_kg if given, else the table's
    moving_mass_kg, else its deck_mass_kg; None when none is known."""
    if moving_mass_kg is not None:
        mass = float(moving_mass_kg)
        if not (math.isfinite(mass) and mass > 0.0):
            raise ValueError(f"moving_mass_kg must be positive, got {moving_mass_kg!r}")
        return mass
    table = table or {}
    return _number(table, "moving_mass_kg") or _number(table, "deck_mass_kg")


def missing_for_analytic(table: Mapping[str, Any] | None, moving_mass_kg: float | None = None) -> list[str]:
    """Names of the table-description fields the analytic frequency lacks (empty when it can be computed)."""
    table = table or {}
    missing = [f"oil.{key}" for key in ("bulk_modulus_pa", "piston_area_m2", "oil_volume_m3")
               if _number(table, "oil", key) is None]
    if empty_moving_mass(table, moving_mass_kg) is None:
        missing.append("deck_mass_kg")
    return missing


def analytic_oil_frequency(
    table: Mapping[str, Any] | None,
    payload_kg: float = 0.0,
    *,
    chambers: int = 2,
    moving_mass_kg: float | None = None,
) -> float:
    """f_oil = (1/2pi)*sqrt(chambers*beta*A^2/(V*M)), Hz, from a series' `table` description.

    table: the manifest's table (oil.bulk_modulus_pa, oil.piston_area_m2, oil.oil_volume_m3
    and deck_mass_kg or moving_mass_kg); payload_kg: mass fixed on the deck, added to the
    moving mass; chambers: 2 (V per chamber, the default) or 4 (V the total), see the module;
    moving_mass_kg: the empty table's moving mass, overriding the table's.

    Raises ValueError naming the fields that are missing or not positive numbers.
    """
    if chambers not in CHAMBER_FORMS:
        raise ValueError(f"chambers must be 2 (V per chamber) or 4 (V the total), got {chambers!r}")
    payload = float(payload_kg)
    if not (math.isfinite(payload) and payload >= 0.0):
        raise ValueError(f"payload_kg must be zero or positive, got {payload_kg!r}")
    missing = missing_for_analytic(table, moving_mass_kg)
    if missing:
        raise ValueError("the table description lacks " + ", ".join(missing)
                         + " (positive numbers) for the analytic oil-column frequency")
    table = table or {}
    return oil_column_frequency(
        _number(table, "oil", "bulk_modulus_pa"),
        _number(table, "oil", "piston_area_m2"),
        _number(table, "oil", "oil_volume_m3"),
        empty_moving_mass(table, moving_mass_kg) + payload,
        chambers=chambers,
    )


def oil_frequency_vs_payload(
    table: Mapping[str, Any] | None,
    payloads: Iterable[float],
    *,
    chambers: int = 2,
    moving_mass_kg: float | None = None,
) -> list[tuple[float, float]]:
    """[(payload_kg, f_oil_hz), ...]: the analytic frequency for each payload, in the order given.

    f_oil falls as 1/sqrt(M0 + payload): 10 t on the sst-paper table (M0 = 13.2 t) takes
    28.6 Hz down to 21.6 Hz, 25 t to 16.8 Hz.
    """
    return [(float(p), analytic_oil_frequency(table, p, chambers=chambers, moving_mass_kg=moving_mass_kg))
            for p in payloads]
