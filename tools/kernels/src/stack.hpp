// The stacked rows A Φ = b of docs/design.md §3 for a batch of samples, written into preallocated arrays.
//
// The Python reference is dynid.robot.regressors.stack.fill_rows; the plan below is that function's structure as
// data (dynid.robot.regressors.kernel builds it from the robot model), so the kernel holds no robot knowledge.
#pragma once

#include "chain.hpp"

#include <vector>

namespace dynid {

// A sparse linear term: value = Σ coef · source[index]
struct Term {
    int index;
    double coef;
};

struct StackPlan {
    int rows = 0;        // r: rows per sample
    int columns = 0;     // p
    int inertial0 = 0;   // first inertial column (10 per body)
    std::vector<std::vector<Term>> inertial;  // per row: Pinocchio regressor rows (index = v row) it combines
    struct Constant { int row, column; double value; };
    std::vector<Constant> constants;           // the F/T offsets' identity
    struct Measured { int row, column; };
    std::vector<Measured> ft;                  // b[row] = ft[:, column]
    struct Coordinate {                        // a friction coordinate: a joint, or a coupled motor at q̇_m = T q̇
        std::vector<Term> velocity;            // over the columns of q̇
        int column;                            // first of its four friction parameters
        std::vector<Term> shares;              // index = row
    };
    std::vector<Coordinate> friction;
    struct Input {                             // a motor input, or a measured joint torque
        int source;                            // its column in the inputs (or torques) array
        int column;                            // its gain's parameter column, -1: moved to b
        std::vector<Term> shares;              // index = row
    };
    std::vector<Input> inputs, torques;
};

struct StackInputs {
    const double *q, *dq, *ddq;  // (N, n_joints) each
    const double* inputs;        // (N, n_inputs) or null
    long n_inputs;
    const double* torques;       // (N, n_torques) or null
    long n_torques;
    const double* ft;            // (N, 6 n_sensors) or null
    long n_ft;
    const double* gravity;       // (N, 3) or null
    const double* payload;       // (10 n_bodies) or null
    const double* weights;       // (N, r) or null
    long n_joints;
};

// Output element strides (in doubles): A[k, row, col], b[k, row]. With `phi` set, A and b are not written: the
// residuals b − A Φ go to e[k, row] (contiguous (N, r)) instead.
struct StackOutput {
    double* A;
    long sA0, sA1, sA2;
    double* b;
    long sb0, sb1;
    // Residuals only: b − A Φ_m per row for each of `n_phi` parameter vectors (rows of phi), into e[m] (N, rows).
    const double* phi = nullptr;
    double* e = nullptr;
    int n_phi = 1;
    long e_stride = 0;  // between e[m] and e[m + 1]
};

class Stack {
public:
    Stack(Chain chain, StackPlan plan);
    const Chain& chain() const { return chain_; }
    const StackPlan& plan() const { return plan_; }
    // Samples [begin, end) of `in` into `out` (every entry of A and b written), on `threads` threads.
    void fill(const StackInputs& in, const StackOutput& out, long begin, long end, int threads) const;

private:
    void fill_range(const StackInputs& in, const StackOutput& out, long begin, long end) const;
    Chain chain_;
    StackPlan plan_;
};

}  // namespace dynid
