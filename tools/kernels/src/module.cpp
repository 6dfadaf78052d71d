// dynid._kernels: the compiled batch kernels of dynid (docs/benchmarks.md, "Compiled kernels").
//
// Every function works over a whole array of samples at once and writes into arrays the caller allocated; the GIL
// is released while it runs. The Python implementations stay the reference (dynid.kernels says which runs).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "bindings.hpp"
#include "csv_text.hpp"
#include "stack.hpp"

namespace nb = nanobind;
using namespace dynid;

namespace {

using JointTuple = std::tuple<int, int, std::array<double, 9>, std::array<double, 3>, std::array<double, 3>, int, int, int>;
using Terms = std::vector<std::pair<int, double>>;

std::vector<Term> terms(const Terms& t) {
    std::vector<Term> out;
    for (const auto& [i, c] : t) out.push_back({i, c});
    return out;
}

Chain make_chain(const std::vector<JointTuple>& joints, const std::array<double, 3>& gravity) {
    std::vector<Joint> js;
    for (const auto& [parent, kind, R, p, axis, q_col, v_row, nv] : joints) {
        if (kind < Revolute || kind > Held) throw std::invalid_argument("chain: unknown joint kind");
        Joint J;
        J.parent = parent;
        J.kind = kind;
        J.R = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(R.data());
        J.p = Vec3(p[0], p[1], p[2]);
        J.axis = Vec3(axis[0], axis[1], axis[2]);
        J.q_col = q_col;
        J.v_row = v_row;
        J.nv = nv;
        js.push_back(J);
    }
    return Chain(std::move(js), Vec3(gravity[0], gravity[1], gravity[2]));
}

StackInputs gather(const Stack& s, const CArray2& q, const CArray2& dq, const CArray2& ddq,
                   const std::optional<CArray2>& inputs, const std::optional<CArray2>& torques,
                   const std::optional<CArray2>& ft, const std::optional<CArray2>& gravity,
                   const std::optional<CArray1>& payload, const std::optional<CArray2>& weights) {
    const StackPlan& P = s.plan();
    const long n = rows_of(q, "q", s.chain().n_joints_configured());
    same_shape(dq, q, "dq");
    same_shape(ddq, q, "ddq");
    StackInputs in{q.data(), dq.data(), ddq.data(), nullptr, 0, nullptr, 0, nullptr, 0, nullptr, nullptr,
                   nullptr, static_cast<long>(q.shape(1))};
    long need = 0;
    for (const auto& u : P.inputs) need = std::max<long>(need, u.source + 1);
    if (need) {
        if (!inputs) throw std::invalid_argument("the plan needs inputs");
        in.n_inputs = rows_of(*inputs, "inputs", -1) == n ? static_cast<long>(inputs->shape(1)) : -1;
        if (in.n_inputs < need) throw std::invalid_argument("inputs: wrong shape");
        in.inputs = inputs->data();
    }
    need = 0;
    for (const auto& u : P.torques) need = std::max<long>(need, u.source + 1);
    if (need) {
        if (!torques) throw std::invalid_argument("the plan needs torques");
        in.n_torques = rows_of(*torques, "torques", -1) == n ? static_cast<long>(torques->shape(1)) : -1;
        if (in.n_torques < need) throw std::invalid_argument("torques: wrong shape");
        in.torques = torques->data();
    }
    need = 0;
    for (const auto& f : P.ft) need = std::max<long>(need, f.column + 1);
    if (need) {
        if (!ft) throw std::invalid_argument("the plan needs F/T measurements");
        in.n_ft = rows_of(*ft, "ft", -1) == n ? static_cast<long>(ft->shape(1)) : -1;
        if (in.n_ft < need) throw std::invalid_argument("ft: wrong shape");
        in.ft = ft->data();
    }
    if (gravity) {
        shape2(*gravity, n, 3, "gravity");
        in.gravity = gravity->data();
    }
    if (payload) {
        if (payload->shape(0) != static_cast<size_t>(10 * s.chain().n_bodies()))
            throw std::invalid_argument("payload: one value per inertial parameter");
        in.payload = payload->data();
    }
    if (weights) {
        shape2(*weights, n, P.rows, "weights");
        in.weights = weights->data();
    }
    return in;
}

}  // namespace

NB_MODULE(_kernels, m) {
    m.doc() = "dynid's compiled batch kernels (stacked regressor rows, momentum observer, plant)";

    nb::class_<Chain>(m, "Chain")
        .def(nb::new_(&make_chain), nb::arg("joints"), nb::arg("gravity"),
             "joints: (parent, kind 0 revolute / 1 prismatic / 2 held, R row-major, p, axis, q column, v row, nv)")
        .def_prop_ro("nv", &Chain::nv)
        .def_prop_ro("n_bodies", &Chain::n_bodies)
        .def(
            "regressor",
            [](const Chain& c, CArray2 q, CArray2 dq, CArray2 ddq, std::optional<CArray2> gravity, Array3 Y) {
                const long n = rows_of(q, "q", c.n_joints_configured());
                same_shape(dq, q, "dq");
                same_shape(ddq, q, "ddq");
                if (gravity) shape2(*gravity, n, 3, "gravity");
                if (Y.shape(0) != static_cast<size_t>(n) || Y.shape(1) != static_cast<size_t>(c.nv()) ||
                    Y.shape(2) != static_cast<size_t>(10 * c.n_bodies()) || Y.stride(2) != 1)
                    throw std::invalid_argument("Y must be (N, nv, 10 n_bodies) with contiguous rows");
                nb::gil_scoped_release release;
                ChainState s(c.joints().size());
                for (long k = 0; k < n; ++k)
                    c.regressor(q.data() + k * q.shape(1), dq.data() + k * q.shape(1), ddq.data() + k * q.shape(1),
                                gravity ? gravity->data() + 3 * k : nullptr, s, Y.data() + k * Y.stride(0), Y.stride(1));
            },
            nb::arg("q"), nb::arg("dq"), nb::arg("ddq"), nb::arg("gravity").none(), nb::arg("Y"),
            "Pinocchio's joint-torque regressor of every sample into Y (N, nv, 10 n_bodies)");

    nb::class_<Stack>(m, "Stack")
        .def(
            "__init__",
            [](Stack* self, const Chain& chain, int rows, int columns, int inertial0, const std::vector<Terms>& inertial,
               const std::vector<std::tuple<int, int, double>>& constants, const std::vector<std::pair<int, int>>& ft,
               const std::vector<std::tuple<Terms, int, Terms>>& friction,
               const std::vector<std::tuple<int, int, Terms>>& inputs,
               const std::vector<std::tuple<int, int, Terms>>& torques) {
                StackPlan P;
                P.rows = rows;
                P.columns = columns;
                P.inertial0 = inertial0;
                for (const auto& t : inertial) P.inertial.push_back(terms(t));
                for (const auto& [r, c, v] : constants) P.constants.push_back({r, c, v});
                for (const auto& [r, c] : ft) P.ft.push_back({r, c});
                for (const auto& [v, col, shares] : friction) P.friction.push_back({terms(v), col, terms(shares)});
                for (const auto& [src, col, shares] : inputs) P.inputs.push_back({src, col, terms(shares)});
                for (const auto& [src, col, shares] : torques) P.torques.push_back({src, col, terms(shares)});
                new (self) Stack(chain, std::move(P));
            },
            nb::arg("chain"), nb::arg("rows"), nb::arg("columns"), nb::arg("inertial0"), nb::arg("inertial"),
            nb::arg("constants"), nb::arg("ft"), nb::arg("friction"), nb::arg("inputs"), nb::arg("torques"))
        .def_prop_ro("rows", [](const Stack& s) { return s.plan().rows; })
        .def_prop_ro("columns", [](const Stack& s) { return s.plan().columns; })
        .def(
            "fill",
            [](const Stack& s, CArray2 q, CArray2 dq, CArray2 ddq, std::optional<CArray2> inputs,
               std::optional<CArray2> torques, std::optional<CArray2> ft, std::optional<CArray2> gravity,
               std::optional<CArray1> payload, std::optional<CArray2> weights, Array3 A, Array2 b, int threads) {
                const StackPlan& P = s.plan();
                StackInputs in = gather(s, q, dq, ddq, inputs, torques, ft, gravity, payload, weights);
                const long n = static_cast<long>(q.shape(0));
                if (A.shape(0) != static_cast<size_t>(n) || A.shape(1) != static_cast<size_t>(P.rows) ||
                    A.shape(2) != static_cast<size_t>(P.columns))
                    throw std::invalid_argument("A must be (N, rows, columns)");
                if (b.shape(0) != static_cast<size_t>(n) || b.shape(1) != static_cast<size_t>(P.rows))
                    throw std::invalid_argument("b must be (N, rows)");
                StackOutput out{A.data(), A.stride(0), A.stride(1), A.stride(2), b.data(), b.stride(0), b.stride(1)};
                nb::gil_scoped_release release;
                s.fill(in, out, 0, n, threads);
            },
            nb::arg("q"), nb::arg("dq"), nb::arg("ddq"), nb::arg("inputs").none(), nb::arg("torques").none(),
            nb::arg("ft").none(), nb::arg("gravity").none(), nb::arg("payload").none(), nb::arg("weights").none(),
            nb::arg("A"), nb::arg("b"), nb::arg("threads") = 1,
            "The stacked rows of every sample into A (N, rows, columns) and b (N, rows), any strides, weighted "
            "by `weights` (N, rows) where given")
        .def(
            "residuals",
            [](const Stack& s, CArray2 q, CArray2 dq, CArray2 ddq, std::optional<CArray2> inputs,
               std::optional<CArray2> torques, std::optional<CArray2> ft, std::optional<CArray2> gravity,
               std::optional<CArray1> payload, CArray1 phi, CArray2Out e, int threads) {
                const StackPlan& P = s.plan();
                StackInputs in = gather(s, q, dq, ddq, inputs, torques, ft, gravity, payload, std::nullopt);
                const long n = static_cast<long>(q.shape(0));
                if (phi.shape(0) != static_cast<size_t>(P.columns)) throw std::invalid_argument("phi: one value per column");
                if (e.shape(0) != static_cast<size_t>(n) || e.shape(1) != static_cast<size_t>(P.rows))
                    throw std::invalid_argument("e must be (N, rows)");
                StackOutput out{nullptr, 0, 0, 0, nullptr, 0, 0, phi.data(), e.data()};
                nb::gil_scoped_release release;
                s.fill(in, out, 0, n, threads);
            },
            nb::arg("q"), nb::arg("dq"), nb::arg("ddq"), nb::arg("inputs").none(), nb::arg("torques").none(),
            nb::arg("ft").none(), nb::arg("gravity").none(), nb::arg("payload").none(), nb::arg("phi"), nb::arg("e"),
            nb::arg("threads") = 1, "b − A Φ of every sample's rows into e (N, rows), A never stored")
        .def(
            "residuals_many",
            [](const Stack& s, CArray2 q, CArray2 dq, CArray2 ddq, std::optional<CArray2> inputs,
               std::optional<CArray2> torques, std::optional<CArray2> ft, std::optional<CArray2> gravity,
               std::optional<CArray1> payload, CArray2 phi,
               nb::ndarray<double, nb::ndim<3>, nb::c_contig, nb::device::cpu> e, int threads) {
                const StackPlan& P = s.plan();
                StackInputs in = gather(s, q, dq, ddq, inputs, torques, ft, gravity, payload, std::nullopt);
                const long n = static_cast<long>(q.shape(0));
                if (phi.shape(1) != static_cast<size_t>(P.columns) || phi.shape(0) < 1)
                    throw std::invalid_argument("phi: (K, columns), K ≥ 1");
                if (e.shape(0) != phi.shape(0) || e.shape(1) != static_cast<size_t>(n) ||
                    e.shape(2) != static_cast<size_t>(P.rows))
                    throw std::invalid_argument("e must be (K, N, rows)");
                StackOutput out{nullptr, 0, 0, 0, nullptr, 0, 0, phi.data(), e.data(),
                                static_cast<int>(phi.shape(0)), n * P.rows};
                nb::gil_scoped_release release;
                s.fill(in, out, 0, n, threads);
            },
            nb::arg("q"), nb::arg("dq"), nb::arg("ddq"), nb::arg("inputs").none(), nb::arg("torques").none(),
            nb::arg("ft").none(), nb::arg("gravity").none(), nb::arg("payload").none(), nb::arg("phi"), nb::arg("e"),
            nb::arg("threads") = 1,
            "b − A Φ_m of every sample's rows into e[m] (K, N, rows) for each row Φ_m of phi (K, columns): the rows "
            "built once for all K");

    m.def(
        "csv_rows",
        [](CArray2 values, const std::vector<bool>& integer) {
            const long rows = static_cast<long>(values.shape(0)), columns = static_cast<long>(values.shape(1));
            if (integer.size() != static_cast<size_t>(columns))
                throw std::invalid_argument("integer: one flag per column");
            const std::unique_ptr<bool[]> flags(new bool[size_t(columns)]);
            std::copy(integer.begin(), integer.end(), flags.get());
            std::string text;
            {
                nb::gil_scoped_release release;
                append_csv_rows(values.data(), rows, columns, flags.get(), text);
            }
            return nb::bytes(text.data(), text.size());
        },
        nb::arg("values"), nb::arg("integer"),
        "The CSV lines of `values` (N, columns): each value as Python's repr(float) writes it, or as an integer "
        "where `integer` says so (whole values of at most 2^53)");

    register_observer(m);
    register_plant(m);
}
