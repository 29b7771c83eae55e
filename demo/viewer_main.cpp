// graphfrac-viewer: a scene in a window (demo/viewer_app.h).
#include "viewer_app.h"

int main(int argc, char** argv) { return gf::demo::viewerMain(argc, argv); }
