#include "linecloud/apps/commands.h"

int main(int argc, char** argv) { return linecloud::RunLinecloud(argc, argv); }
