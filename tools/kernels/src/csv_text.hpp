// CSV text of a block of samples, each value as Python's repr writes it (dynid.io.csv_format.write_csv, whose
// Python is the reference): the shortest digits that read back to the same double, laid out by repr's rule.
#pragma once

#include <string>

namespace dynid {

// Rows of `values` (n_rows × n_cols, row-major), each "v,v,...,v\n", appended to `out`. Column j is written as an
// integer where integer[j] (its values are whole numbers of at most 2^53: the caller checks), else as repr(float).
void append_csv_rows(const double* values, long n_rows, long n_cols, const bool* integer, std::string& out);

}  // namespace dynid
