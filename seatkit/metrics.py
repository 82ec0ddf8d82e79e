"""The evaluation's figures in one place: their ``report.json`` keys, labels, units and meaning.

The report (its pictures, ``report.html``, ``seatkit evaluate``), the web app,
the benchmarks and the documentation (``tools/make_reference.py``) take the
names and units of the evaluation's figures from here, so that a figure is
called and scaled the same way everywhere.

Two groups are shown in the tables:

- :data:`PAPER_TABLE1`: the five quantities of the paper's Table 1 (Leimer
  et al. 2020), in its order;
- :data:`CHECKS`: two figures of ours that the paper does not report, how
  deep the surface reaches into the body and how deep the body lies inside
  the furniture (the refiners' 5 mm requirement, read both ways).

:data:`OTHER` lists the remaining per-person keys of ``report.json``'s
``metrics`` (not shown in the tables). :mod:`seatkit.evaluate` computes them
all; :mod:`seatkit.dimensions` computes :data:`DIMENSIONS`.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Metric", "PAPER_TABLE1", "CHECKS", "TABLE", "OTHER", "DIMENSIONS", "PERSON_FIT", "INTERFACE", "TABLE_CAPTION", "CHECKS_NOTE", "columns"]


@dataclass(frozen=True)
class Metric:
    """One figure of the evaluation.

    Attributes
    ----------
    key : str
        Its key in ``report.json`` -> ``metrics`` (the value there is SI).
    label : str
        Its short name in tables.
    unit : str
        The unit it is shown in.
    scale : float
        Shown value = SI value * scale.
    description : str
        What it measures, one or two sentences.
    """

    key: str
    label: str
    unit: str
    scale: float
    description: str


#: The paper's Table 1 quantities, in its order.
PAPER_TABLE1: tuple[Metric, ...] = (
    Metric(
        "avg_distance_m", "avg. dist.", "cm", 100.0,
        "Mean distance from the supported body vertices (those carrying at least 1% of the peak of the "
        "importance map, on the segments the cage supports) to the closest point of the limit surface. "
        "The paper measures to the closest surface vertex.",
    ),
    Metric("avg_moment_nm", "avg. moment", "N m", 1.0, "Mean joint-moment magnitude over the 20 joints, with the recomputed contact."),
    Metric("max_moment_nm", "max. moment", "N m", 1.0, "Largest joint-moment magnitude over the 20 joints."),
    Metric(
        "avg_pressure_pa", "avg. press.", "Pa", 1.0,
        "Mean contact pressure over the contact set (the body vertices within the support distance of the surface), as the paper computes it: "
        "the paper's relative importance, which shares the weight over the contact, in Pa but not a measured interface pressure "
        "(that is metrics.interface).",
    ),
    Metric("max_pressure_pa", "max. press.", "Pa", 1.0, "Largest contact pressure on the body (the paper's relative importance, as above)."),
)

#: Figures of ours shown after the paper's (not in the paper).
CHECKS: tuple[Metric, ...] = (
    Metric(
        "max_penetration_m", "max. penetration", "mm", 1000.0,
        "How deep the surface reaches into the body: the largest depth below the closed skin of any point of the "
        "level-3 limit surface (vertices and quad centres). Not in the paper.",
    ),
    Metric(
        "max_body_depth_m", "max. body depth", "mm", 1000.0,
        "How deep any body vertex lies inside the furniture (the solid the surface closes with the floor). "
        "It also catches a thin part pushed right through the surface. Not in the paper.",
    ),
)

#: Every figure the tables show: the paper's five, then our two checks.
TABLE: tuple[Metric, ...] = PAPER_TABLE1 + CHECKS

#: The other per-person keys of ``report.json`` -> ``metrics`` -> ``ours`` / ``baseline``.
OTHER: tuple[Metric, ...] = (
    Metric("avg_loaded_pressure_pa", "avg. loaded press.", "Pa", 1.0, "Mean pressure over the vertices that carry load (above 1 Pa)."),
    Metric("loaded_vertices", "loaded vertices", "", 1.0, "How many body vertices carry load (above 1 Pa)."),
    Metric("contact_vertices", "contact vertices", "", 1.0, "Size of the contact set: body vertices within the support distance of the surface."),
    Metric("contact_area_m2", "contact area", "m²", 1.0, "Skin area of the contact set."),
    Metric("supported_vertices", "supported vertices", "", 1.0, "How many body vertices the average distance is taken over."),
)

#: ``report.json`` -> ``metrics`` -> ``dimensions``: per person, where the final surface carries the body.
DIMENSIONS: tuple[Metric, ...] = (
    Metric("seat_height_m", "seat height", "m", 1.0, "Mean height of the loaded thigh vertices within 3 cm of the frontmost one (the seat's front edge)."),
    Metric("seat_depth_m", "seat depth", "m", 1.0, "Front-to-back extent of the loaded hips and thighs."),
    Metric("seat_width_m", "seat width", "m", 1.0, "Side-to-side extent of the loaded hips and thighs."),
    Metric("back_height_m", "back height", "m", 1.0, "Top of the loaded back above the lowest loaded hips or thigh vertex; 0 when the back is not carried."),
)

#: ``report.json`` -> ``metrics`` -> ``person_fit``: per person, the seat beside the person (ANSI/HFES 100).
PERSON_FIT: tuple[Metric, ...] = (
    Metric("popliteal_height_m", "popliteal height", "m", 1.0, "The person's popliteal height, measured on their body (seatkit.body.measure)."),
    Metric("shoe_allowance_m", "shoe allowance", "m", 1.0, "Added to the popliteal height for a seat height with shoes on (25 mm, ANSI/HFES 100)."),
    Metric("seat_height_for_shoes_m", "seat height for shoes", "m", 1.0, "Popliteal height plus the shoe allowance: the seat height the standard asks for."),
    Metric("seat_height_difference_m", "seat height difference", "m", 1.0, "The design's seat height minus the seat height for shoes."),
    Metric("buttock_popliteal_length_m", "buttock-popliteal length", "m", 1.0, "The person's buttock-popliteal length; the seat depth should stay short of it."),
    Metric("seat_depth_difference_m", "seat depth difference", "m", 1.0, "The design's seat depth minus the buttock-popliteal length."),
    Metric("hip_breadth_sitting_m", "hip breadth, sitting", "m", 1.0, "The person's hip breadth; the seat should be at least as wide."),
    Metric("seat_width_difference_m", "seat width difference", "m", 1.0, "The design's seat width minus the hip breadth."),
)

#: ``report.json`` -> ``metrics`` -> ``interface``: per person, the soft-tissue model on our design (not the paper's).
INTERFACE: tuple[Metric, ...] = (
    Metric("peak_pa", "peak interface pressure", "kPa", 1e-3, "Largest interface pressure on the skin: soft tissue over the skeleton on the rigid design, comparable with a pressure mat."),
    Metric("seat_peak_pa", "seat peak", "kPa", 1e-3, "Largest interface pressure under the buttocks and thighs."),
    Metric("mean_loaded_pa", "mean loaded pressure", "kPa", 1e-3, "Mean interface pressure over the loaded skin."),
    Metric("contact_area_m2", "loaded area", "cm²", 1e4, "Skin area that carries load."),
    Metric("max_joint_moment_nm", "max. moment", "N m", 1.0, "Largest joint moment with this contact."),
    Metric("max_compression_m", "max. compression", "mm", 1000.0, "Deepest compression of the soft tissue."),
    Metric("max_strain", "max. strain", "%", 100.0, "Deepest compression as a share of the tissue's thickness there."),
    Metric("youngs_modulus_pa", "Young's modulus", "kPa", 1e-3, "Stiffness of the soft tissue the model assumes."),
)

#: The heading of the tables' quantity column.
TABLE_CAPTION = "Table 1, then 2 checks of ours"
#: One line under (or beside) a table that shows :data:`TABLE`.
CHECKS_NOTE = (
    "The first five rows are the quantities of the paper's Table 1 (Leimer et al. 2020); "
    "max. penetration and max. body depth are ours (not in the paper): how deep the surface "
    "reaches into the body, and how deep the body lies inside the furniture."
)


def columns(metrics: tuple[Metric, ...] = TABLE) -> tuple[tuple[str, str, str, float], ...]:
    """``(key, label, unit, scale)`` of each metric, the tuple form the tables use."""
    return tuple((m.key, m.label, m.unit, m.scale) for m in metrics)
