"""Yarns: where a fabric's yarn comes from and what the solvers read from it.

- :mod:`~knitframe.yarn.library`: a yarn from a config value (a library name, a table of fields,
  or ``like = "cotton"`` with overrides), the ``[yarns]`` table and the yarn-model plugin instance;
- :mod:`~knitframe.yarn.properties`: the quantities the solvers read from a yarn, marked measured,
  estimate or derived, and the stiffnesses derived from the record (shear, effective bending);
- :mod:`~knitframe.yarn.fit`: yarn parameters from tension and compression tests, and the Hertz
  line contact they rely on.

The yarn record itself is :class:`knitframe.records.Yarn`, which does not import this package.
"""

from knitframe.yarn.fit import (
    COLUMNS,
    CompressionFit,
    TensionFit,
    fit_compression,
    fit_tension,
    fit_yarn,
    line_contact_approach,
    line_contact_load,
    line_contact_stiffness,
    pretension,
    read_test,
)
from knitframe.yarn.library import config_yarns, resolve_yarn, yarn_model
from knitframe.yarn.properties import (
    SHEAR_COEFFICIENT,
    YarnProperty,
    effective_bending,
    shear_length,
    shear_stiffness,
    yarn_properties,
)

__all__ = [
    "resolve_yarn",
    "config_yarns",
    "yarn_model",
    "yarn_properties",
    "YarnProperty",
    "SHEAR_COEFFICIENT",
    "effective_bending",
    "shear_stiffness",
    "shear_length",
    "COLUMNS",
    "TensionFit",
    "CompressionFit",
    "read_test",
    "fit_tension",
    "fit_compression",
    "fit_yarn",
    "pretension",
    "line_contact_approach",
    "line_contact_load",
    "line_contact_stiffness",
]
