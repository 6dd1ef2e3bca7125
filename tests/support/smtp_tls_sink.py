#!/usr/bin/python3
"""An SMTP sink that requires STARTTLS, for the server's e-mail notifications in tests.

Debian's python3-aiosmtpd with its Mailbox handler: every message goes into MAILDIR/new. Before a
client has said STARTTLS, MAIL and RCPT are refused (530), so a message in the maildir came over TLS.

  smtp_tls_sink.py HOST PORT CERT.pem KEY.pem MAILDIR
"""
import signal
import ssl
import sys
import threading

from aiosmtpd.controller import Controller
from aiosmtpd.handlers import Mailbox


def main():
    if len(sys.argv) != 6:
        sys.exit("usage: smtp_tls_sink.py HOST PORT CERT.pem KEY.pem MAILDIR")
    host, port, cert, key, maildir = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    context.load_cert_chain(cert, key)
    controller = Controller(Mailbox(maildir), hostname=host, port=port, tls_context=context, require_starttls=True)
    controller.start()
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    while not stop.wait(0.2):
        pass
    controller.stop()


if __name__ == "__main__":
    main()
