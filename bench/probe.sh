set -x
export PATH=$PATH:/usr/local/cuda/bin PYTHONPATH=$PWD/python
cp -r .carry/eigen3 /usr/include/ && mkdir -p /usr/share/eigen3/cmake && cp .carry/eigen3-cmake/* /usr/share/eigen3/cmake/
cat > /tmp/p.cu <<'X'
#include <cstdio>
#include <cuda_runtime.h>
int main(){int n=0; auto e=cudaGetDeviceCount(&n); printf("count %d %d\n",(int)e,n); cudaDeviceProp p; e=cudaGetDeviceProperties(&p,0); printf("prop %d %s\n",(int)e,p.name); e=cudaFree(nullptr); printf("free %d\n",(int)e);}
X
nvcc -o /tmp/p /tmp/p.cu && /tmp/p
echo LD=$LD_LIBRARY_PATH
BUILD_DIR=/tmp/sffd-build PYTHON=$(command -v python3) CMAKE_ARGS="-DSMOOTHFFD_TESTS=OFF" bash scripts/build.sh > $OUT/build.log 2>&1; echo build $?
ldd python/smoothffd/_core*.so | grep -i -E "cuda|cublas"
cuda-gdb -batch -ex run -ex bt --args python3 -c "import smoothffd; print(smoothffd.cuda_status())" 2>&1 | tail -30
