"""ABAQUS and FEBio exports of the reduced models, parsed back and checked against the model."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from knitframe.errors import KnitframeError
from knitframe.plugins import get_registry


def parse_abaqus(text: str) -> dict:
    """Minimal reader of the exported card: keyword lines, their data lines and the ``**`` comments."""
    out: dict = {"comments": [], "keywords": {}}
    current = None
    for raw in text.splitlines():
        line = raw.strip()
        if not line:
            continue
        if line.startswith("**"):
            out["comments"].append(line[2:].strip())
        elif line.startswith("*"):
            head, *params = [p.strip() for p in line[1:].split(",")]
            current = head.upper()
            out["keywords"][current] = {"params": [p.upper() for p in params], "data": []}
        else:
            out["keywords"][current]["data"].append(
                [float(x) if _is_number(x) else x for x in line.split(",")]
            )
    return out


def _is_number(x: str) -> bool:
    try:
        float(x)
        return True
    except ValueError:
        return False


def fibre_energy(ksi, alpha, i4):
    """FEBio fiber-exp-pow with β = 2: Ψ = ξ/(2α)(exp[α(I_n − 1)²] − 1), tension only."""
    x = np.maximum(i4 - 1, 0)
    return ksi / (2 * alpha) * np.expm1(alpha * x**2)


def test_abaqus_card_maps_k1_2a_k2_b_kappa_0_fibre_at_theta():
    """The HOLZAPFEL card holds k1 = 2a, k2 = b, κ = 0 and the fibre direction (cos θ, sin θ, 0)."""
    m = get_registry()["homogenizer"]["hgo"]()
    a, b, th = 0.26, 15.9, math.radians(53.7)
    card = parse_abaqus(m.abaqus(np.array([a, b, th]), name="JERSEY"))
    kw = card["keywords"]
    assert kw["MATERIAL"]["params"] == ["NAME=JERSEY"]
    holz = kw["ANISOTROPIC HYPERELASTIC"]
    assert "HOLZAPFEL" in holz["params"] and "LOCAL DIRECTIONS=1" in holz["params"]
    c10, d, k1, k2, kappa = holz["data"][0]
    assert k1 == pytest.approx(2 * a) and k2 == pytest.approx(b) and kappa == 0.0
    assert c10 > 0 and c10 < 0.01 * k1 and d == 0.0  # a small matrix, stated in the comments
    direction = kw["ORIENTATION"]["data"][-1]
    np.testing.assert_allclose(direction, [math.cos(th), math.sin(th), 0.0], atol=1e-9)
    text = " ".join(card["comments"]).lower()
    assert "compression" in text and "isochoric" in text and "matrix" in text


def test_abaqus_card_divides_by_thickness():
    """Per-area energies become per-volume ones: k1 = 2a / t."""
    m = get_registry()["homogenizer"]["hgo"]()
    card = parse_abaqus(m.abaqus(np.array([0.3, 2.0, 0.5]), thickness=1.5))
    assert card["keywords"]["ANISOTROPIC HYPERELASTIC"]["data"][0][2] == pytest.approx(0.4)


def test_febio_block_reproduces_the_fibre_energy():
    """The FEBio fiber-exp-pow parsed back (ξ = 2a, α = b, β = 2) gives hgo's energy along the fibre in
    tension."""
    m = get_registry()["homogenizer"]["hgo"]()
    a, b, th = 0.05, 3.0, math.radians(30)
    root = ET.fromstring(m.febio(np.array([a, b, th])))
    assert root.tag == "material" and root.get("type") == "solid mixture"
    solids = root.findall("solid")
    assert [s.get("type") for s in solids] == ["neo-Hookean", "fiber-exp-pow"]
    fib = solids[1]
    ksi, alpha, beta = (float(fib.findtext(t)) for t in ("ksi", "alpha", "beta"))
    assert beta == 2.0
    assert float(fib.find("fiber").findtext("theta")) == pytest.approx(30.0)
    assert float(fib.find("fiber").findtext("phi")) == 90.0
    lam = np.linspace(1.0, 1.3, 7)  # equibiaxial: I4 = λ² whatever θ
    np.testing.assert_allclose(
        fibre_energy(ksi, alpha, lam**2), m.energy(np.array([a, b, th]), lam, lam), rtol=1e-12
    )
    text = m.febio(np.array([a, b, th]))
    assert "<!--" in text and "compression" in text and "isochoric" in text


def test_hgo2m_febio_has_course_and_wale_fibres():
    """hgo2m exports two fiber-exp-pow families at 0° and 90° with their own ξ = 2a_i/t and α = b_i."""
    m = get_registry()["homogenizer"]["hgo2m"]()
    p = np.array([0.03, 0.01, 0.01, 0.02, 2.0, 0.05, 1.0])
    root = ET.fromstring(m.febio(p, thickness=2.0))
    fibres = [s for s in root.findall("solid") if s.get("type") == "fiber-exp-pow"]
    got = [
        (float(f.findtext("ksi")), float(f.findtext("alpha")), float(f.find("fiber").findtext("theta")))
        for f in fibres
    ]
    assert got == [pytest.approx((0.02, 2.0, 0.0)), pytest.approx((0.05, 1.0, 90.0))]
    nh = root.find("solid[@type='neo-Hookean']")
    E, v = float(nh.findtext("E")), float(nh.findtext("v"))
    G = E / (2 * (1 + v))
    assert G == pytest.approx(0.01 / 2.0)  # isotropic part: min(mu1, mu2) / t
    assert v == pytest.approx(0.01 / (2 * 0.01 + 0.01))  # small-strain Poisson ratio K / (2 mu + K)


def test_hgo2m_has_no_abaqus_card():
    """hgo2m refuses an ABAQUS HOLZAPFEL card with a one-line reason instead of writing a wrong one."""
    m = get_registry()["homogenizer"]["hgo2m"]()
    with pytest.raises(KnitframeError, match="shares k1, k2") as e:
        m.abaqus(m.x0())
    assert "\n" not in str(e.value)
