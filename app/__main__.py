from app.cli.streams import repair_std_streams

repair_std_streams()                    # before ufl keeps a reference to sys.stdout

from app.cli.main import main  # noqa: E402
from app.cli.startup import quick_exit  # noqa: E402

quick_exit(main())      # an exception propagates as usual (traceback, exit status 1)
