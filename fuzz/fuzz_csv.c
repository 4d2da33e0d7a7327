/* libFuzzer target: bsurf_read_buffer as CSV (corpus/fuzz_csv). */
#define FUZZ_FORMAT BSURF_FORMAT_CSV
#include "fuzz_reader.h"
