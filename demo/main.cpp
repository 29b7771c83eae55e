// graphfrac-demo: renders a scene off-screen (demo/demo_app.h).
#include "demo_app.h"

int main(int argc, char** argv) { return gf::demo::demoMain(argc, argv); }
