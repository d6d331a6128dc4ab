"""The model's own guard (issue 34, "inputs out of the physics"): :class:`adm_sim.model.bridge.Bridge`
checks physical invariants only and raises :class:`adm_sim.errors.ModelError` (finite and positive
lengths, stiffness and mass, a damping ratio in [0, 1), a whole mode count >= 1, one EJ and mu per
span, the deck length the sum of its spans). The input ranges are the readers' (adm_sim.inputs with
the field registry): a value inside the invariants but outside the registry's range is the model's
to compute and the reader's to refuse, with the user's own name for it."""

import math

import pytest

from adm_sim.errors import AdmSimError, InputError, ModelError
from adm_sim.fields import FIELDS
from adm_sim.inputs.bridges import parse_bridge_spec
from adm_sim.model.bridge import BRIDGE_TYPES, DAMPING_MODELS, Bridge

OK = dict(span_m=15.0, EJ_Nm2=2.667e10, mass_per_length_kg_m=19042.0, damping_ratio=0.0185)


@pytest.mark.parametrize("over,match", [
    (dict(span_m=0.0), r"Bridge.span_m: 0.0 m must be finite and > 0"),
    (dict(span_m=math.nan), r"Bridge.span_m: nan m must be finite and > 0"),
    (dict(EJ_Nm2=-1.0), r"Bridge.EJ_Nm2: -1.0 N m\^2 must be finite and > 0"),
    (dict(mass_per_length_kg_m=math.inf), r"Bridge.mass_per_length_kg_m: inf kg/m must be finite and > 0"),
    (dict(mass_per_length_kg_m="heavy"), r"Bridge.mass_per_length_kg_m: 'heavy' is not a number \(kg/m\)"),
    (dict(damping_ratio=-0.01), r"Bridge.damping_ratio: -0.01 must be a fraction in \[0, 1\)"),
    (dict(damping_ratio=1.0), r"Bridge.damping_ratio: 1.0 must be a fraction in \[0, 1\)"),
    (dict(n_modes=0), r"Bridge.n_modes: 0 must be an integer >= 1"),
    (dict(n_modes=2.5), r"Bridge.n_modes: 2.5 must be an integer >= 1"),
    (dict(damping_model="viscous"), r"Bridge.damping_model: 'viscous' is not one of"),
    (dict(bridge_type="steel"), r"Bridge.bridge_type: 'steel' is not one of"),
    (dict(span_m=40.0, spans_m=(15.0, 25.0), span_EJ_Nm2=(1e10,), span_mu_kg_m=(1e4, 1e4)),
     r"Bridge.span_EJ_Nm2: 1 values for 2 spans"),
    (dict(span_m=40.0, spans_m=(15.0, -25.0), span_EJ_Nm2=(1e10, 1e10), span_mu_kg_m=(1e4, 1e4)),
     r"Bridge.spans_m\[1\]: -25.0 m must be finite and > 0"),
    (dict(span_m=41.0, spans_m=(15.0, 25.0), span_EJ_Nm2=(1e10, 1e10), span_mu_kg_m=(1e4, 1e4)),
     r"Bridge.span_m: 41 m is not the deck length 40 m"),
])
def test_invariants(over, match):
    with pytest.raises(ModelError, match=match):
        Bridge(**{**OK, **over})


def test_model_error_is_an_error_of_the_house_not_an_input_error():
    """ModelError sits under the root (a command line shows it as one line, exit 1) and is no
    InputError (bad input is the readers' to refuse, exit 2)."""
    assert issubclass(ModelError, AdmSimError) and not issubclass(ModelError, InputError)


def test_outside_the_registry_is_the_readers_to_refuse():
    """A 200 m span and 25 modes break no invariant: the model computes them; the reader refuses the
    same values as the user typed them, with the registry's range."""
    b = Bridge(**{**OK, "span_m": 200.0, "n_modes": 25})
    assert b.n0_hz == pytest.approx(math.pi / (2 * 200.0**2) * math.sqrt(OK["EJ_Nm2"] / OK["mass_per_length_kg_m"]),
                                    rel=1e-15)
    with pytest.raises(InputError, match=r"^bridge spec.L: 200 m is out of range; allowed \[1, 150\] m$"):
        parse_bridge_spec("L=200,n0=1,mu=19042,zeta_pct=1.85")
    with pytest.raises(InputError, match=r"^bridge spec.n_modes: 25 is out of range; allowed integer in \[1, 20\]$"):
        parse_bridge_spec("L=15,n0=8.26,mu=19042,zeta_pct=1.85,n_modes=25")


def test_the_models_vocabularies_are_the_registrys_choices():
    """The damping models and bridge types the model implements are the choices a user may type."""
    assert DAMPING_MODELS == FIELDS["damping_model"].choices
    assert BRIDGE_TYPES == FIELDS["bridge_type"].choices
