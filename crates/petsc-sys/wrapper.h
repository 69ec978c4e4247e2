/* The PETSc headers deasim binds: KSP pulls in PC, Mat, Vec, the options database and MPI. */
#include <petscksp.h>
