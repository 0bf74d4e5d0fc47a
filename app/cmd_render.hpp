// `cutsim render`: one offscreen picture of a tet mesh (registered by registerCommands).
#pragma once

namespace CLI {
class App;
}

namespace cutsim::app {

void addRenderCommand(CLI::App& app);  // cmd_render.cpp

}  // namespace cutsim::app
