// Lennard-Jones between the sites of different bodies: lgvi::LennardJones,
// defined in forces/lennard_jones.hpp (kept here for code that includes this
// header).
#pragma once

#include <lgvi/forces/lennard_jones.hpp>
