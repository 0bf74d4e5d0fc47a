// OpenGL 3.3 core declarations for render/ sources. Functions come from libGL (glvnd exports the
// core entry points and dispatches to the context EGL made current), so no loader is needed.
#pragma once

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
