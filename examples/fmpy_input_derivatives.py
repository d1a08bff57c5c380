"""Work around fmpy 0.3.32's ``simulate_fmu(..., set_input_derivatives=True)``.

The bug (fmpy 0.3.32, ``fmpy.simulation.Input.__init__``): the buffer for the
input derivatives of each group of continuous Real inputs is allocated as
``(value_type * 9)()`` whatever the number of inputs, and ``Input.apply`` then
does ``derivatives[:] = d`` with one derivative per input. For any FMU that
does not have exactly 9 continuous Real inputs this raises
``ValueError: Can only assign sequence of same size``, so
``simulate_fmu(set_input_derivatives=True)`` cannot run at all with
``HillMuscle1D`` (2 inputs: ``activation`` and ``length``).

The patch: ``SizedDerivativesInput`` subclasses fmpy's ``Input``, runs fmpy's
own ``__init__`` unchanged and only re-allocates that buffer with one element
per input. The input values and derivatives fmpy computes (the slope of the
piecewise-linear input table) and the calls it makes
(``fmi2SetReal`` / ``fmi2SetRealInputDerivatives``) are untouched.
``simulate_fmu`` looks ``Input`` up in the module ``fmpy.simulation`` when it
runs, so ``fixed_fmpy_input()`` replaces ``fmpy.simulation.Input`` by the
subclass for the duration of a ``with`` block and always restores the
original, also when the simulation raises. The replacement is process-wide
while the block runs (do not run other fmpy simulations concurrently in other
threads).

Usage::

    from fmpy_input_derivatives import simulate_with_input_derivatives

    result = simulate_with_input_derivatives(
        "dist/HillMuscle1D.fmu", stop_time=1.0, output_interval=1e-3,
        input=signals, output=["stress"])

If the installed fmpy already sizes the buffer correctly the patch is a no-op
(the buffer is re-allocated with the same size).
"""

from __future__ import annotations

import contextlib

import fmpy.simulation

FMPY_INPUT = fmpy.simulation.Input
"""fmpy's own ``Input`` class (captured when this module is imported)."""


class SizedDerivativesInput(FMPY_INPUT):
    """fmpy's ``Input`` with the input-derivative buffer of each group of
    continuous inputs sized to the number of inputs in the group."""

    def __init__(self, fmu, modelDescription, signals, set_input_derivatives=False):
        super().__init__(fmu, modelDescription, signals, set_input_derivatives)
        if getattr(self, "continuous", None):
            self.continuous = [
                c._replace(derivatives=(type(c.derivatives)._type_ * len(c.vrs))())
                for c in self.continuous
            ]


@contextlib.contextmanager
def fixed_fmpy_input():
    """Within the block ``fmpy.simulation.Input`` is ``SizedDerivativesInput``;
    on leaving it (normally or by an exception) it is what it was before."""
    previous = fmpy.simulation.Input
    fmpy.simulation.Input = SizedDerivativesInput
    try:
        yield SizedDerivativesInput
    finally:
        fmpy.simulation.Input = previous


def simulate_with_input_derivatives(filename, **simulate_fmu_kwargs):
    """``fmpy.simulate_fmu(filename, set_input_derivatives=True,
    **simulate_fmu_kwargs)`` with the fixed ``Input``; returns its result.

    ``set_input_derivatives`` is always True here: call ``fmpy.simulate_fmu``
    directly for a run without input derivatives.
    """
    if "set_input_derivatives" in simulate_fmu_kwargs:
        raise TypeError("simulate_with_input_derivatives always sets input derivatives; "
                        "do not pass set_input_derivatives")
    with fixed_fmpy_input():
        return fmpy.simulation.simulate_fmu(str(filename), set_input_derivatives=True, **simulate_fmu_kwargs)
