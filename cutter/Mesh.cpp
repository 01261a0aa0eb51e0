#include "cutter/Mesh.h"
