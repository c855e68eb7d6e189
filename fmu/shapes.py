"""Array shapes of the FMI 3.0 TrailerTrain FMU for a chosen n, for fmpy.

fmpy resolves each ``<Dimension valueReference=...>`` from the *start* value in the XML (n = 3),
once, when it reads the model description; it does not re-read n after setting it. To simulate
another n with ``fmpy.simulate_fmu``, pass the model description this module returns together
with the start value of ``n``::

    md = model_description_for("TrailerTrain3.fmu", 10)
    simulate_fmu("TrailerTrain3.fmu", model_description=md, start_values={"n": 10, ...})
"""

from __future__ import annotations

from pushtrain.errors import FmuInputError

from .render import check_n

__all__ = ["model_description_for"]


def model_description_for(fmu, n_trailers: int):
    """fmpy's model description of the FMI 3.0 FMU ``fmu`` with its arrays sized for
    ``n_trailers`` (the start values of ``n`` and ``n_bodies`` say n and n + 1)."""
    from fmpy import read_model_description

    n = check_n(n_trailers)
    md = read_model_description(str(fmu))
    if md.fmiVersion != "3.0":
        raise FmuInputError(f"{fmu}: fmiVersion {md.fmiVersion}; array shapes exist in FMI 3.0 "
                            "only (an FMI 2.0 FMU is built for its n)")
    by_name = {v.name: v for v in md.modelVariables}
    by_name["n"].start = str(n)
    by_name["n_bodies"].start = str(n + 1)
    for var in md.modelVariables:
        if var.dimensions:
            var.shape = tuple(int(d.start) if d.start is not None else int(d.variable.start)
                              for d in var.dimensions)
            if var.start is not None:  # the start of an array is n (or n + 1) times its element
                var.start = " ".join([var.start.split()[0]] * var.shape[0])
    return md
