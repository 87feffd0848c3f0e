"""docs/dask.md: a TLS Dask cluster of this machine, with certificates made by openssl as
the page says (ca.pem, client.pem, client.key in the snippet's folder), and a small MR1
campaign of the reference pipeline."""

import shutil
import subprocess

import pytest

if shutil.which("openssl") is None:
    pytest.skip("openssl is not installed", allow_module_level=True)
pytest.importorskip("distributed")

from distributed import LocalCluster
from distributed.security import Security as _Security

from pytest_metamorphic.lidar.campaign import mr1_campaign
from pytest_metamorphic.lidar.systems.perception import ReferencePerception

SUBSTITUTE = {'"tls://A:8786"': "SCHEDULER"}


def _openssl(*args: str) -> None:
    subprocess.run(["openssl", *args], check=True, capture_output=True)


_openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=mt-ca",
         "-keyout", "ca.key", "-out", "ca.pem")  # fmt: skip
_openssl("req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=localhost",
         "-keyout", "client.key", "-out", "client.csr")  # fmt: skip
_openssl("x509", "-req", "-in", "client.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
         "-CAcreateserial", "-days", "1", "-out", "client.pem")  # fmt: skip
_cluster_security = _Security(
    tls_ca_file="ca.pem", tls_scheduler_cert="client.pem", tls_scheduler_key="client.key",
    tls_worker_cert="client.pem", tls_worker_key="client.key",
    tls_client_cert="client.pem", tls_client_key="client.key", require_encryption=True,
)  # fmt: skip
_cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tls",
                        security=_cluster_security, dashboard_address=None)  # fmt: skip
SCHEDULER = _cluster.scheduler_address
campaign = mr1_campaign(ReferencePerception(), name="MR1 on TLS", sources=2, sizes=(10,))
