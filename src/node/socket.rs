//! The DDS sockets' receive buffer. The participant asks for [`SOCKET_BUFFER`] with
//! `SO_RCVBUF`, which Linux clamps to `net.core.rmem_max` (4 MiB on many hosts: less than one
//! camera-sized cloud, which arrives as one burst of datagrams). Where the process may
//! (`CAP_NET_ADMIN`: root, or a service given the capability), the node forces the size on its
//! UDP sockets with `SO_RCVBUFFORCE`, which is not clamped; elsewhere the clamp stands and the
//! node warns (docs/host-setup.md), at start and for a source whose messages outgrow what the
//! kernel grants.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Kernel socket buffer asked for, bytes (SO_RCVBUF and SO_SNDBUF; the kernel clamps it to
/// `net.core.rmem_max`/`wmem_max`). A 640×480 cloud of 32-byte points is 9.8 MB, which
/// arrives as one burst of about 150 datagrams: the buffer must hold it while the reader
/// reassembles.
pub const SOCKET_BUFFER: usize = 64 << 20;

/// Bytes forced on the process's UDP sockets (0: none forced).
static FORCED: AtomicUsize = AtomicUsize::new(0);

/// Forces a receive buffer of `bytes` on every UDP socket this process has open (the DDS
/// participant's, made just before). `Ok(n)`: the sockets that took it; an error when the
/// process may not (`EPERM`: no `CAP_NET_ADMIN`) or the sockets cannot be listed.
pub fn force_receive_buffers(bytes: usize) -> std::io::Result<usize> {
    let size = libc::c_int::try_from(bytes).unwrap_or(libc::c_int::MAX);
    let mut forced = 0;
    for entry in std::fs::read_dir("/proc/self/fd")? {
        let entry = entry?;
        let is_socket = std::fs::read_link(entry.path())
            .is_ok_and(|target| target.to_string_lossy().starts_with("socket:"));
        let Some(fd) = entry
            .file_name()
            .to_str()
            .and_then(|n| n.parse::<libc::c_int>().ok())
        else {
            continue;
        };
        if !is_socket || socket_type(fd) != Some(libc::SOCK_DGRAM) {
            continue;
        }
        // SAFETY: `fd` is an open socket of this process (listed above) and `size` lives for
        // the call; a descriptor closed meanwhile only makes the call fail.
        let r = unsafe {
            libc::setsockopt(
                fd,
                libc::SOL_SOCKET,
                libc::SO_RCVBUFFORCE,
                (&size as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if r != 0 {
            return Err(std::io::Error::last_os_error());
        }
        forced += 1;
    }
    if forced > 0 {
        FORCED.store(bytes, Ordering::Relaxed);
    }
    Ok(forced)
}

/// `SO_TYPE` of socket `fd`.
fn socket_type(fd: libc::c_int) -> Option<libc::c_int> {
    let mut ty: libc::c_int = 0;
    let mut len = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
    // SAFETY: `ty` and `len` are valid for writes of the sizes given.
    let r = unsafe {
        libc::getsockopt(
            fd,
            libc::SOL_SOCKET,
            libc::SO_TYPE,
            (&mut ty as *mut libc::c_int).cast(),
            &mut len,
        )
    };
    (r == 0).then_some(ty)
}

/// What a socket that asks for `requested` receive-buffer bytes gets: all of it where this
/// process forced it, else Linux's clamp to `net.core.rmem_max`; `None` where that is not
/// readable.
pub fn granted_receive_buffer(requested: usize) -> Option<usize> {
    let forced = FORCED.load(Ordering::Relaxed);
    if forced >= requested {
        return Some(requested);
    }
    let max = std::fs::read_to_string("/proc/sys/net/core/rmem_max").ok()?;
    Some(requested.min(max.trim().parse().ok()?))
}

/// Whether the buffers were forced.
pub fn forced() -> bool {
    FORCED.load(Ordering::Relaxed) > 0
}

pub(super) fn mib(bytes: usize) -> String {
    format!("{:.1} MiB", bytes as f64 / (1 << 20) as f64)
}

/// What the granted socket buffer means for a source's messages of `bytes`: a message larger
/// than the buffer arrives as one burst the kernel cannot hold, so whole messages are lost
/// (measured: 9.8 MB clouds with 4 MiB granted, 12–13 % lost at 30 Hz; docs/host-setup.md).
pub(super) fn warn_burst(source: &str, what: &str, bytes: usize) {
    if let Some(granted) = granted_receive_buffer(SOCKET_BUFFER).filter(|&g| bytes > g) {
        log::warn!(
            "source {source}: each {what} is {}, more than the {} socket receive buffer the \
             kernel grants (net.core.rmem_max): expect lost {what}s and reassembly memory; \
             raise rmem_max to at least {} (docs/host-setup.md), or publish depth images \
             (type: depth_image)",
            mib(bytes),
            mib(granted),
            mib((2 * bytes).next_power_of_two()),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forcing_takes_every_udp_socket_or_says_why_not() {
        let udp = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let _tcp = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        match force_receive_buffers(8 << 20) {
            Ok(n) => {
                // With CAP_NET_ADMIN: the UDP socket holds the size (Linux reports it doubled),
                // whatever rmem_max says; the TCP listener is left.
                assert!(n >= 1);
                let mut got: libc::c_int = 0;
                let mut len = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
                use std::os::fd::AsRawFd;
                // SAFETY: valid pointers of the sizes given.
                let r = unsafe {
                    libc::getsockopt(
                        udp.as_raw_fd(),
                        libc::SOL_SOCKET,
                        libc::SO_RCVBUF,
                        (&mut got as *mut libc::c_int).cast(),
                        &mut len,
                    )
                };
                assert_eq!(r, 0);
                assert!(got >= 8 << 20, "SO_RCVBUF {got}");
                assert_eq!(granted_receive_buffer(8 << 20), Some(8 << 20));
            }
            Err(e) => assert_eq!(e.raw_os_error(), Some(libc::EPERM), "{e}"),
        }
    }
}
