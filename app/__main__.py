from app.cli.streams import repair_std_streams

repair_std_streams()                    # before ufl keeps a reference to sys.stdout

from app.cli.main import main
from app.startup import quick_exit

quick_exit(main())      # an exception propagates as usual (traceback, exit status 1)
