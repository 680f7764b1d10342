"""CasADi callbacks that hand IPOPT the stage's numpy derivatives (layer L3, private).

``GradF`` (``nlp_grad_f``: cost and gradient), ``Hess`` (``nlp_hess_l``: the Hessian of
the Lagrangian, upper triangle) and ``Cost`` (the objective of a problem without a CasADi
residual, with its gradient as Jacobian) read and write CasADi's buffers directly.
"""

import numpy as np

from .. import _interrupt

__all__ = []


def _grad_f_class(ca):
    class GradF(ca.Callback):
        """``nlp_grad_f``: (x, p) -> (f, grad f) from ``gradient(x) -> (f, grad)``."""

        def __init__(self, n, gradient):
            ca.Callback.__init__(self)
            self.gradient = gradient
            self.n = n
            _interrupt.construct(self, "nlp_grad_f")

        def get_n_in(self):
            return 2

        def get_n_out(self):
            return 2

        def get_name_in(self, i):
            return ("x", "p")[i]

        def get_name_out(self, i):
            return ("f", "grad_f")[i]

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(self.n, 1) if i == 0 else ca.Sparsity.dense(0, 1)

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(1, 1) if i == 0 else ca.Sparsity.dense(self.n, 1)

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            # copy-free: read x from and write (f, grad) into CasADi's own buffers
            x = np.frombuffer(arg[0], dtype=np.float64)
            cost, grad = self.gradient(x.copy())
            if res[0] is not None:              # an output not asked for is None
                np.frombuffer(res[0], dtype=np.float64)[0] = cost
            if res[1] is not None:
                np.frombuffer(res[1], dtype=np.float64)[:] = grad
            return 0

    return GradF


def _hess_class(ca):
    class Hess(ca.Callback):
        """``nlp_hess_l``: (x, p, lam_f, lam_g) -> triu(lam_f * Hessian of the cost)."""

        def __init__(self, n, hessian, kind, hess_g=None):
            ca.Callback.__init__(self)
            self.hessian = hessian
            self.hess_g = hess_g
            self.ng = 0 if hess_g is None else hess_g.numel_in(1)
            self.exact = kind != "gauss-newton"
            self.n = n
            self.sp = ca.Sparsity.upper(n)
            rows, cols = np.triu_indices(n)
            order = np.lexsort((rows, cols))                 # column-major nonzero order
            self.flat = rows[order] * n + cols[order]        # into the row-major Hessian
            _interrupt.construct(self, "nlp_hess_l")

        def get_n_in(self):
            return 4

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ("x", "p", "lam_f", "lam_g")[i]

        def get_name_out(self, i):
            return "hess_gamma_x_x"

        def get_sparsity_in(self, i):
            return [ca.Sparsity.dense(self.n, 1), ca.Sparsity.dense(0, 1),
                    ca.Sparsity.dense(1, 1), ca.Sparsity.dense(self.ng, 1)][i]

        def get_sparsity_out(self, i):
            return self.sp

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            x = np.frombuffer(arg[0], dtype=np.float64).copy()
            lam_f = float(np.frombuffer(arg[2], dtype=np.float64)[0])
            if res[0] is None:
                return 0
            # the upper triangle straight into CasADi's buffer, then scaled there (the same
            # products as scaling first: one multiplication per entry)
            out = np.frombuffer(res[0], dtype=np.float64)
            np.take(self.hessian(x, exact=self.exact).ravel(), self.flat, out=out)
            out *= lam_f
            if self.ng:
                lam_g = (np.zeros(self.ng) if arg[3] is None
                         else np.frombuffer(arg[3], dtype=np.float64))
                out += self.hess_g(x, lam_g).full().ravel().take(self.flat)
            return 0

    return Hess


def _cost_class(ca):
    class Cost(ca.Callback):
        """``f``: x -> cost(x), for a problem without a CasADi residual."""

        def __init__(self, n, cost, grad_cb):
            ca.Callback.__init__(self)
            self.cost = cost
            self.grad_cb = grad_cb
            self.n = n
            _interrupt.construct(self, "nlp_f_callback")

        def get_n_in(self):
            return 1

        def get_n_out(self):
            return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(self.n, 1)

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(1, 1)

        def eval(self, arg):
            return [float(self.cost(np.array(arg[0], float).reshape(-1)))]

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            # copy-free: read x from and write the cost into CasADi's own buffers
            if res[0] is not None:
                x = np.frombuffer(arg[0], dtype=np.float64).copy()
                np.frombuffer(res[0], dtype=np.float64)[0] = self.cost(x)
            return 0

        def has_jacobian(self):
            return True

        def get_jacobian(self, name, inames, onames, opts):
            # d cost/dx from the problem's gradient (a GradF of the same problem)
            x = ca.MX.sym(inames[0], self.n)
            out = ca.MX.sym(inames[1], 1)
            grad = self.grad_cb(x, ca.MX(0, 1))[1]
            return ca.Function(name, [x, out], [grad.T], inames, onames, opts)

    return Cost


def _make_callbacks():
    import casadi as ca

    return _grad_f_class(ca), _hess_class(ca), _cost_class(ca)


_CALLBACKS = []


def _callback_classes():
    if not _CALLBACKS:
        _CALLBACKS.extend(_make_callbacks())
    return _CALLBACKS


def _GradF(n, gradient):
    return _callback_classes()[0](n, gradient)


def _Hess(n, hessian, kind, hess_g=None):
    return _callback_classes()[1](n, hessian, kind, hess_g)


def _Cost(n, cost, grad_cb):
    return _callback_classes()[2](n, cost, grad_cb)
