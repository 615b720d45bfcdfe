r"""Fitting reduced fabric models to Responses: the objective, its gradient and the result record.

A reduced model (a :class:`~knitframe.interfaces.Homogenizer`) used here also offers
``bounds()``, ``x0()``, ``log_scale``, ``predicts_lateral``, ``stress_grad(params, λ1, λ2)`` →
``(P1, P2, ∂P1/∂p, ∂P2/∂p)`` and ``tangent(params, λ1, λ2)`` → ``(∂P1/∂λ1, ∂P1/∂λ2, ∂P2/∂λ2)``.

How each Response enters the fit (:class:`FitProblem`):

* ``equibiaxial`` / ``general``: both stretches are imposed; P1 is compared with T1 and P2 with T2.
* ``uniaxial-course`` / ``uniaxial-wale`` (free sides): the loaded tension is compared. A model
  that cannot predict the free side (``predicts_lateral = False``, the paper's ``hgo``) is
  evaluated at the *measured* free-side stretch; its free-side tension, which should be zero, is
  reported as the diagnostic ``free_side_tension`` (max |P_free| / max |T_loaded|). A model that
  can (``predicts_lateral = True``) gets its free-side stretch from P_free = 0
  (:func:`solve_free_side`); the difference to the measured transverse strain is a second
  residual group.

Score and objective. Residuals are grouped by direction (course, wale) and kind (tension,
transverse strain). ``NRMSE_g = sqrt(mean_g r²) / max_g |measured|`` — normalised by the maximum
measured tension of that direction (transverse: maximum |transverse strain|), and ``overall``
over all tension residuals by the overall maximum. The fitters minimise

.. math:: J(p) = \sum_{g \in \text{tension}} \mathrm{NRMSE}_g^2
               + w_t \sum_{g \in \text{transverse}} \mathrm{NRMSE}_g^2

which is the paper's least-squares objective Σ‖S − P‖² with each direction weighted by its own
scale, so a stiff and a soft direction count equally. Its gradient is exact: stress derivatives
from the model, and for a solved free side the implicit derivative
``∂λf/∂p = −(∂P_f/∂p) / (∂P_f/∂λf)``.

The package holds one concept per module: :mod:`~knitframe.fitting.free_side` (the free side of a
uniaxial test), :mod:`~knitframe.fitting.params` (params.json), :mod:`~knitframe.fitting.problem`
(the objective and its gradient), :mod:`~knitframe.fitting.result` (the result record, the
fitters' unit box and start design, :func:`finish`) and :mod:`~knitframe.fitting.outputs`
(predicted curves, the fit figure and files). A fitter plugin needs nothing else of the core but
:func:`one_blas_thread` (:mod:`knitframe.numerics.parallel`), exported here: many small solves in
one process run fastest on one BLAS thread.
"""

from knitframe.fitting.free_side import (
    DIRECTIONS,
    FREE_MIN,
    bracketed_newton,
    direction_index,
    free_side_grad,
    free_side_zero_message,
    solve_free_side,
)
from knitframe.fitting.outputs import plot_fit, predict, write_fit_outputs
from knitframe.fitting.params import finite_json, params_from_json, params_to_json, within_model_bounds
from knitframe.fitting.problem import RESIDUAL_CLIP, FitProblem
from knitframe.fitting.result import AT_BOUND, FitResult, UnitBox, at_bound, finish, start_design
from knitframe.numerics.parallel import one_blas_thread

__all__ = [
    "FREE_MIN",
    "RESIDUAL_CLIP",
    "AT_BOUND",
    "DIRECTIONS",
    "direction_index",
    "solve_free_side",
    "bracketed_newton",
    "free_side_grad",
    "params_to_json",
    "within_model_bounds",
    "params_from_json",
    "FitProblem",
    "FitResult",
    "UnitBox",
    "start_design",
    "predict",
    "write_fit_outputs",
    "plot_fit",
    "at_bound",
    "finish",
    "finite_json",
    "free_side_zero_message",
    "one_blas_thread",
]
