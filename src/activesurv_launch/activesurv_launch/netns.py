"""Several "hosts" on one machine: Linux network namespaces joined by veth pairs on a bridge.

:class:`NetnsHosts` makes one namespace per host (``as<id>-core``, ``as<id>-cam1`` ...), each
with its own loopback and one veth interface on the bridge ``as<id>br`` of the root namespace,
addresses ``10.<net>.0.<n>/24`` and a multicast route so that DDS discovery works as on a LAN.
Nodes are started in a host with ``ip netns exec``. Needs root (CAP_NET_ADMIN) and ``ip``;
:func:`unavailable_reason` says why not where they are missing. Everything made is removed on
exit, also after errors.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
from collections.abc import Sequence
from types import TracebackType

from activesurv_launch.errors import LaunchError


class NetnsError(LaunchError):
    """Network namespaces cannot be made or torn down."""


def _ip(*args: str, ns: str | None = None) -> subprocess.CompletedProcess[str]:
    cmd = (['ip', 'netns', 'exec', ns, 'ip'] if ns else ['ip']) + list(args)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=20, check=False)
    if r.returncode != 0:
        raise NetnsError(f'{" ".join(cmd)} failed: {r.stderr.strip() or r.stdout.strip()}')
    return r


def _setns(fd: int, what: str) -> None:

    libc = ctypes.CDLL(None, use_errno=True)
    if libc.setns(fd, 0x40000000) != 0:  # CLONE_NEWNET
        raise NetnsError(f'setns into {what} failed: {os.strerror(ctypes.get_errno())}')


def unavailable_reason() -> str | None:
    """Why network namespaces cannot be used here, or None if they can."""
    if shutil.which('ip') is None:
        return 'the ip command (iproute2) is not installed'
    if os.geteuid() != 0:
        return 'creating network namespaces needs root (CAP_NET_ADMIN)'
    probe = f'asprobe{os.getpid() % 100000}'
    r = subprocess.run(
        ['ip', 'netns', 'add', probe], capture_output=True, text=True, timeout=20, check=False
    )
    if r.returncode != 0:
        return f'ip netns add failed: {r.stderr.strip()}'
    subprocess.run(['ip', 'netns', 'del', probe], capture_output=True, timeout=20, check=False)
    return None


class NetnsHosts:
    """Namespaces ``hosts`` on a private bridge; use as a context manager."""

    def __init__(self, hosts: Sequence[str], net: int | None = None) -> None:
        if not hosts or len(set(hosts)) != len(hosts):
            raise NetnsError(f'hosts must be distinct and not empty: {list(hosts)}')
        if len(hosts) > 200:
            raise NetnsError('at most 200 hosts')
        tag = os.getpid() % 10000
        self.net = net if net is not None else 100 + os.getpid() % 150
        self.bridge = f'as{tag}br'
        self.names = {h: f'as{tag}-{h}' for h in hosts}
        self.addresses = {h: f'10.{self.net}.0.{10 + i}' for i, h in enumerate(hosts)}
        self.gateway = f'10.{self.net}.0.1'
        self._made: list[tuple[str, str]] = []
        self._root_fd: int | None = None

    def namespace(self, host: str) -> str:
        return self.names[host]

    def prefix(self, host: str) -> list[str]:
        """The command prefix that runs a program in ``host``."""
        return ['ip', 'netns', 'exec', self.names[host]]

    def __enter__(self) -> NetnsHosts:
        try:
            self._up()
        except Exception:
            self.close()
            raise
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _up(self) -> None:
        _ip('link', 'add', self.bridge, 'type', 'bridge')
        self._made.append(('link', self.bridge))
        _ip('addr', 'add', f'{self.gateway}/24', 'dev', self.bridge)
        _ip('link', 'set', self.bridge, 'type', 'bridge', 'mcast_snooping', '0')
        _ip('link', 'set', self.bridge, 'up')
        for i, (host, ns) in enumerate(self.names.items()):
            _ip('netns', 'add', ns)
            self._made.append(('netns', ns))
            outer, inner = f'{self.bridge[:-2]}v{i}', 'eth0'
            _ip('link', 'add', outer, 'type', 'veth', 'peer', 'name', f'{outer}p')
            self._made.append(('link', outer))
            _ip('link', 'set', f'{outer}p', 'netns', ns)
            _ip('link', 'set', outer, 'master', self.bridge)
            _ip('link', 'set', outer, 'up')
            _ip('link', 'set', f'{outer}p', 'name', inner, ns=ns)
            _ip('addr', 'add', f'{self.addresses[host]}/24', 'dev', inner, ns=ns)
            _ip('link', 'set', inner, 'up', ns=ns)
            _ip('link', 'set', 'lo', 'up', ns=ns)
            _ip('route', 'add', '224.0.0.0/4', 'dev', inner, ns=ns)

    def enter(self, host: str) -> None:
        """Move this process into ``host``'s namespace (before it creates any DDS participant)."""

        if self._root_fd is None:
            self._root_fd = os.open('/proc/self/ns/net', os.O_RDONLY)
        fd = os.open(f'/var/run/netns/{self.names[host]}', os.O_RDONLY)
        try:
            _setns(fd, self.names[host])
        finally:
            os.close(fd)

    def traffic_bytes(self) -> dict[str, int]:
        """Bytes received plus sent on each host's interface (proof that traffic crossed)."""
        out = {}
        for host, ns in self.names.items():
            r = subprocess.run(
                [
                    'ip',
                    'netns',
                    'exec',
                    ns,
                    'cat',
                    '/sys/class/net/eth0/statistics/rx_bytes',
                    '/sys/class/net/eth0/statistics/tx_bytes',
                ],
                capture_output=True,
                text=True,
                timeout=20,
                check=False,
            )
            out[host] = sum(int(x) for x in r.stdout.split()) if r.returncode == 0 else -1
        return out

    def close(self) -> None:
        if self._root_fd is not None:  # back to the root namespace, where the bridge is
            _setns(self._root_fd, 'the root namespace')
            os.close(self._root_fd)
            self._root_fd = None
        for kind, name in reversed(self._made):
            args = ['netns', 'del', name] if kind == 'netns' else ['link', 'del', name]
            subprocess.run(['ip', *args], capture_output=True, timeout=20, check=False)
        self._made.clear()
