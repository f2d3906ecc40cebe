"""N-term Ogden material on isochoric stretches (Comley and Fleck used a one-term Ogden for
porcine adipose tissue): W = sum_p 2 mu_p / alpha_p^2 (l1^alpha_p + l2^alpha_p + l3^alpha_p - 3).

The built-in ``ogden`` has three terms; ``ogden_terms(n)`` builds any other count. Set a mu_p to
a tiny value to switch a term off. Defaults are illustrative (initial shear modulus sum mu_p ~ 1 kPa).
"""

from cfm_core.material.parameters import Parameter, positive
from cfm_core.material.terms import isochoric

from .volumetric import ogden_volumetric


def ogden_term(p: int, mu: float, alpha: float):
    """Isochoric Ogden term number p with parameters mu{p} (Pa) and alpha{p} (-, nonzero).

    W_p = 2 mu_p / alpha_p^2 (l1^alpha_p + l2^alpha_p + l3^alpha_p - 3).

    Parameters
    ----------
    p : int
        Term number, used in the parameter names (``mu1``, ``alpha1``, ...) and the term name
        ``ogden-<p>``.
    mu : float
        Default modulus mu_p (Pa), > 0.
    alpha : float
        Default exponent alpha_p (-), in [-50, 50] and nonzero.

    Returns
    -------
    Term
        The isochoric term.

    Raises
    ------
    InputError
        A default outside its range (``mu`` <= 0, ``alpha`` = 0 or beyond +-50).
    """
    mu_par = positive(f"mu{p}", "Pa", mu, f"Ogden modulus of term {p}")
    alpha_par = Parameter(f"alpha{p}", "-", alpha, low=-50.0, high=50.0, nonzero=True, min_abs=1e-3,
                          description=f"Ogden exponent of term {p} (nonzero)")

    def energy(l1, l2, l3, *params):
        mu_p, alpha_p = params
        return 2 * mu_p / alpha_p**2 * (l1**alpha_p + l2**alpha_p + l3**alpha_p - 3)

    return isochoric(mu_par, alpha_par, name=f"ogden-{p}", description=f"Ogden term {p}")(energy)


def ogden_terms(n: int, defaults=((600.0, 10.0), (300.0, -8.0), (100.0, 2.0))):
    """A material spec with n Ogden terms and the Ogden volumetric term (paper Eq. 7).

    Parameters
    ----------
    n : int
        Number of Ogden terms, >= 1.
    defaults : sequence of (float, float)
        Default ``(mu_p (Pa), alpha_p (-))`` per term, reused cyclically when n exceeds its
        length.

    Returns
    -------
    MaterialSpec
        Named ``"ogden"`` for n = 3, else ``"ogden-<n>"``; elastic (no Prony series).

    Raises
    ------
    InputError
        A default outside its range.
    """
    spec = None
    for p in range(1, n + 1):
        mu, alpha = defaults[(p - 1) % len(defaults)]
        term = ogden_term(p, mu, alpha)
        spec = term if spec is None else spec & term
    return (spec & ogden_volumetric).named(f"ogden-{n}" if n != 3 else "ogden",
                                          f"{n}-term Ogden (isochoric) + Ogden volumetric, elastic")


OGDEN = ogden_terms(3)
