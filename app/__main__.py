import sys

try:
    from app.streams import repair_std_streams
    repair_std_streams()                # before ufl keeps a reference to sys.stdout
    from app.cli import main
    from app.startup import quick_exit
except KeyboardInterrupt:               # Ctrl-C / SIGTERM while the modules load
    sys.stderr.write("vpcontact: interrupted while starting; nothing was computed\n")
    raise SystemExit(3) from None

quick_exit(main())      # an exception propagates as usual (traceback, exit status 1)
