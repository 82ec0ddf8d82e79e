"""Materials of the shell: stiffness, Poisson's ratio, strength and density.

Every material is modelled as linear elastic and isotropic (see
docs/structure.md, "Limits"). ``strength_pa`` is the stress the safety
factor is measured against: the yield strength of the metals, the bending
strength of the boards, the tensile strength across the printed layers of
the printed plastics (their weakest direction) and the in-plane tensile
strength of the glass-fibre laminate. Values are typical or lower-bound
figures from the named sources, rounded; a real supplier's data sheet wins.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from seatkit.errors import SeatkitError

__all__ = ["MATERIALS", "Material", "get_material"]


@dataclass(frozen=True)
class Material:
    """A linear-elastic isotropic material.

    Attributes
    ----------
    name : str
    youngs_modulus_pa : float
    poisson_ratio : float
    strength_pa : float
        Stress at which it fails or yields, Pa (see the module docstring).
    density_kg_m3 : float
    description : str
    source : str
    """

    name: str
    youngs_modulus_pa: float
    poisson_ratio: float
    strength_pa: float
    density_kg_m3: float
    description: str
    source: str

    @property
    def lame(self) -> tuple[float, float]:
        """Lamé's first parameter and the shear modulus, Pa."""
        e, nu = self.youngs_modulus_pa, self.poisson_ratio
        return e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))

    def as_dict(self) -> dict:
        return asdict(self)


MATERIALS: dict[str, Material] = {
    m.name: m
    for m in (
        Material(
            "birch-plywood",
            10.0e9,
            0.30,
            40.0e6,
            680.0,
            "birch plywood (cross-laminated veneers), bending along the face grain and across averaged",
            "Handbook of Finnish Plywood, Finnish Forest Industries Federation, 2007 (ISBN 952-9506-66-X): "
            "birch plywood bending stiffness and strength tables, density 680 kg/m3",
        ),
        Material(
            "mdf",
            2.2e9,
            0.25,
            20.0e6,
            750.0,
            "medium-density fibreboard, general purpose, 12-19 mm",
            "EN 622-5:2009, requirements for MDF (type MDF, 12-19 mm): bending strength >= 20 MPa, "
            "modulus of elasticity in bending >= 2200 MPa; density typical",
        ),
        Material(
            "pla",
            3.0e9,
            0.36,
            35.0e6,
            1240.0,
            "PLA as printed (fused filament), strength across the layers",
            "additive.tools materials database, PLA: FDM as-built modulus 3-4 GPa, tensile strength "
            "50-65 MPa along and 35-45 MPa across the layers (lower bounds used), density 1.22-1.26 g/cm3",
        ),
        Material(
            "petg",
            2.0e9,
            0.38,
            25.0e6,
            1270.0,
            "PETG as printed (fused filament), strength across the layers",
            "additive.tools materials database, PETG: FDM as-built modulus 2-3 GPa, tensile strength "
            "44-56 MPa along and 25-38 MPa across the layers (lower bounds used), density 1.25-1.29 g/cm3",
        ),
        Material(
            "aluminium-6061",
            68.9e9,
            0.33,
            276.0e6,
            2700.0,
            "aluminium alloy 6061-T6 sheet, yield strength",
            "ASM Handbook Vol. 2 (1990), Properties of Wrought Aluminum Alloys: 6061-T6, E 68.9 GPa, "
            "tensile yield 276 MPa, density 2.70 g/cm3",
        ),
        Material(
            "steel",
            210.0e9,
            0.30,
            235.0e6,
            7850.0,
            "structural steel S235, yield strength",
            "EN 1993-1-1:2005, 3.2.6 (E 210 GPa, nu 0.3, 7850 kg/m3) and EN 10025-2 (S235: yield 235 MPa)",
        ),
        Material(
            "gfrp",
            17.0e9,
            0.23,
            170.0e6,
            1850.0,
            "glass-fibre reinforced polyester laminate, in-plane tensile strength",
            "EN 13706-3:2002, grade E17 (minimum longitudinal modulus 17 GPa, tensile strength 170 MPa); "
            "density and Poisson's ratio typical of E-glass/polyester",
        ),
    )
}


def get_material(name: str) -> Material:
    """The material called ``name``; an error listing the names otherwise."""
    try:
        return MATERIALS[name]
    except (KeyError, TypeError):
        msg = f"unknown material {name!r}; expected one of {', '.join(MATERIALS)}"
        raise SeatkitError(msg) from None
