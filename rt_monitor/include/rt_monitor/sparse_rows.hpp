// A matrix's nonzero entries row by row (compressed rows), of fixed capacity: the core's products with the row map
// and the external-torque map skip the zeros most of their rows hold (a joint-torque sensor's row names one joint,
// a motor's its coupled joints). The products add the nonzero terms in the dense loop's order, so they give the
// dense loop's value exactly: a zero term adds nothing to a finite sum (at most a zero's sign differs).
#pragma once

#include <array>

namespace dynid::rt {

template <int Rows, int Cols>
class SparseRows {
public:
    // Rows [0, rows) and columns [0, cols) of m (anything with m(i, j)).
    template <class Matrix>
    void assign(const Matrix& m, int rows, int cols) noexcept {
        int n = 0;
        for (int i = 0; i < rows; ++i) {
            start_[i] = n;
            for (int j = 0; j < cols; ++j)
                if (m(i, j) != 0.0) column_[n] = j, value_[n++] = m(i, j);
        }
        start_[rows] = n;
    }
    // Σ_j m(i, j)·x[j] added to s, j ascending.
    double dot(int i, const double* x, double s = 0.0) const noexcept {
        for (int k = start_[i]; k < start_[i + 1]; ++k) s += value_[k] * x[column_[k]];
        return s;
    }
    // out[j] += m(i, j)·a for every nonzero of row i.
    void axpy(int i, double a, double* out) const noexcept {
        for (int k = start_[i]; k < start_[i + 1]; ++k) out[column_[k]] += value_[k] * a;
    }

private:
    std::array<int, Rows + 1> start_{};
    std::array<int, Rows * Cols> column_{};
    std::array<double, Rows * Cols> value_{};
};

}  // namespace dynid::rt
