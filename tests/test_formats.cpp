// Trajectory file formats (src/trajectory_sink.hpp, src/formats/): written by
// the formats' writers, read back independently.
#include <gtest/gtest.h>
