from app.cli import main
from app.startup import quick_exit

quick_exit(main())      # an exception propagates as usual (traceback, exit status 1)
