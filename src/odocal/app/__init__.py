"""One typed function per ``odocal`` command, each returning a frozen result.

What the command line, the tests, the benchmarks and a notebook call. Every function checks its
inputs where they enter, plans its outputs against its inputs before the work
(:class:`odocal.io.outputs.OutputPlan`) and writes all of them or none after it.

============== =========================================
command        function
============== =========================================
design         :func:`odocal.app.design.design`
simulate       :func:`odocal.app.simulate.simulate`
calibrate      :func:`odocal.app.calibrate.calibrate`
plan           :func:`odocal.app.plan.plan`
noise          :func:`odocal.app.noise.noise`
fit            :func:`odocal.app.fit.fit`
validate       :func:`odocal.app.validate.validate`
compare        :func:`odocal.app.compare.compare`
reproduce      :func:`odocal.app.reproduce.reproduce`
ttest          :func:`odocal.app.ttest.ttest`
bag-info       :func:`odocal.app.bag_info.bag_info`
============== =========================================
"""
