from glob import glob

from setuptools import find_packages, setup

package_name = 'activesurv_common'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed', 'data/*.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description=(
        'Shared core: geometry, camera and mount models, sensor model, information fusion '
        '(eq. 2); the topic and QoS contract and the node entry point.'
    ),
    license='Apache-2.0',
)
