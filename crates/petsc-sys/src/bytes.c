/* Point-to-point byte messages between MPI ranks. MPI_BYTE and MPI_UNSIGNED_LONG_LONG are
 * macros whose expansion differs between MPI implementations (a pointer to a global in Open MPI,
 * an integer handle in MPICH) and that bindgen cannot translate: the C compiler expands them here.
 * A message is its length, then its bytes in chunks that fit MPI's int counts. */
#include <mpi.h>

#define DEASIM_CHUNK (1ULL << 30)

int deasim_mpi_send_bytes(const unsigned char *bytes, unsigned long long length, int to, int tag,
                          MPI_Comm comm)
{
    int code = MPI_Send(&length, 1, MPI_UNSIGNED_LONG_LONG, to, tag, comm);
    for (unsigned long long at = 0; code == MPI_SUCCESS && at < length; at += DEASIM_CHUNK) {
        unsigned long long n = length - at < DEASIM_CHUNK ? length - at : DEASIM_CHUNK;
        code = MPI_Send(bytes + at, (int)n, MPI_BYTE, to, tag, comm);
    }
    return code;
}

int deasim_mpi_recv_length(unsigned long long *length, int from, int tag, MPI_Comm comm)
{
    return MPI_Recv(length, 1, MPI_UNSIGNED_LONG_LONG, from, tag, comm, MPI_STATUS_IGNORE);
}

int deasim_mpi_recv_bytes(unsigned char *bytes, unsigned long long length, int from, int tag,
                          MPI_Comm comm)
{
    int code = MPI_SUCCESS;
    for (unsigned long long at = 0; code == MPI_SUCCESS && at < length; at += DEASIM_CHUNK) {
        unsigned long long n = length - at < DEASIM_CHUNK ? length - at : DEASIM_CHUNK;
        code = MPI_Recv(bytes + at, (int)n, MPI_BYTE, from, tag, comm, MPI_STATUS_IGNORE);
    }
    return code;
}
